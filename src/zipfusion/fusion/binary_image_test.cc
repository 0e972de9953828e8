#include "zipfusion/fusion/binary_image.h"

#include <gtest/gtest.h>

#include <opencv2/imgproc.hpp>
#include <random>
#include <vector>

#include "zipfusion/core/allocation_count_test_util.h"

namespace zipfusion {
namespace {

// Binary images as the zipper makes them: a few blobs of 255 (a person's silhouette at some
// level, holes and specks of noise in it), with `density` of the pixels flipped at random, and
// some touching the image's edges.
cv::Mat random_mask(int width, int height, double density, std::mt19937& random) {
  cv::Mat mask(height, width, CV_8UC1, cv::Scalar(0));
  std::uniform_int_distribution<int> x(0, width - 1), y(0, height - 1), r(1, std::max(2, std::min(width, height) / 3));
  for (int k = 0; k < 4; ++k) cv::circle(mask, {x(random), y(random)}, r(random), cv::Scalar(255), cv::FILLED);
  std::bernoulli_distribution flip(density);
  for (int v = 0; v < height; ++v) {
    for (int u = 0; u < width; ++u) {
      if (flip(random)) mask.at<std::uint8_t>(v, u) ^= 255;
    }
  }
  return mask;
}

struct Size {
  int width, height;
};
constexpr Size kSizes[] = {{1, 1}, {1, 7}, {9, 1}, {5, 4}, {33, 17}, {80, 60}, {161, 121}};

TEST(BinaryImage, DilateErodeAndCloseAsOpenCvDoes) {
  std::mt19937 random(1);
  BinaryImageScratch scratch;
  for (const Size size : kSizes) {
    for (const double density : {0.0, 0.05, 0.5}) {
      const cv::Mat mask = random_mask(size.width, size.height, density, random);
      for (int radius = 1; radius <= 4; ++radius) {
        const cv::Mat square = cv::getStructuringElement(cv::MORPH_RECT, {2 * radius + 1, 2 * radius + 1});
        cv::Mat expected, got(mask.size(), CV_8UC1);
        cv::dilate(mask, expected, square);
        dilate_binary(mask.data, got.data, size.width, size.height, radius, scratch);
        ASSERT_EQ(cv::countNonZero(got != expected), 0) << "dilate " << size.width << "x" << size.height << " radius " << radius;
        cv::erode(mask, expected, square);
        erode_binary(mask.data, got.data, size.width, size.height, radius, scratch);
        ASSERT_EQ(cv::countNonZero(got != expected), 0) << "erode " << size.width << "x" << size.height << " radius " << radius;
        cv::morphologyEx(mask, expected, cv::MORPH_CLOSE, square);
        got = mask.clone();
        close_binary(got.data, got.data, size.width, size.height, radius, scratch);  // in place, as the zipper does
        ASSERT_EQ(cv::countNonZero(got != expected), 0) << "close " << size.width << "x" << size.height << " radius " << radius;
      }
    }
  }
}

TEST(BinaryImage, ChamferDistanceAsOpenCvComputesIt) {
  std::mt19937 random(2);
  BinaryImageScratch scratch;
  for (const Size size : kSizes) {
    for (const double density : {0.0, 0.01, 0.3}) {
      cv::Mat mask = random_mask(size.width, size.height, density, random);
      if (size.width * size.height > 4) mask.at<std::uint8_t>(0, 0) = 0;  // at least one zero, in a corner
      cv::Mat expected, got(mask.size(), CV_32FC1);
      cv::distanceTransform(mask, expected, cv::DIST_L2, cv::DIST_MASK_3);
      chamfer_distance(mask.data, got.ptr<float>(), size.width, size.height, scratch);
      for (int v = 0; v < size.height; ++v) {
        for (int u = 0; u < size.width; ++u) {
          ASSERT_EQ(got.at<float>(v, u), expected.at<float>(v, u)) << size.width << "x" << size.height << " at (" << u << ", " << v << ")";
        }
      }
    }
  }
  // Without a zero pixel, and a straight line of them: the distances far out and along a row.
  cv::Mat full(40, 50, CV_8UC1, cv::Scalar(255)), expected, got(full.size(), CV_32FC1);
  cv::distanceTransform(full, expected, cv::DIST_L2, cv::DIST_MASK_3);
  chamfer_distance(full.data, got.ptr<float>(), 50, 40, scratch);
  EXPECT_EQ(cv::countNonZero(got != expected), 0);
  EXPECT_EQ(got.at<float>(20, 25), 8192.0f);
  full.row(0).setTo(0);
  chamfer_distance(full.data, got.ptr<float>(), 50, 40, scratch);
  EXPECT_NEAR(got.at<float>(10, 25), 10 * 0.955f, 1e-3f);
}

TEST(BinaryImage, AllocatesNothingOnceItsScratchHasGrown) {
  std::mt19937 random(3);
  const cv::Mat mask = random_mask(160, 120, 0.05, random);
  std::vector<std::uint8_t> image(mask.data, mask.data + mask.total());
  std::vector<float> distance(image.size());
  BinaryImageScratch scratch;
  auto run = [&] {
    close_binary(image.data(), image.data(), 160, 120, 2, scratch);
    dilate_binary(image.data(), image.data(), 160, 120, 1, scratch);
    chamfer_distance(image.data(), distance.data(), 160, 120, scratch);
  };
  run();
  const long long before = g_allocations.load();
  run();
  run();
  EXPECT_EQ(g_allocations.load() - before, 0);
}

}  // namespace
}  // namespace zipfusion
