#include "zipfusion/depth/bilateral.h"

#include <gtest/gtest.h>

#include <cmath>
#include <random>

namespace zipfusion {
namespace {

// A step edge: 2.0 m on the left, 2.3 m on the right, with Gaussian noise σ = 1 cm, a hole.
Image<float> noisy_step(int width, int height, unsigned seed) {
  std::mt19937 rng(seed);
  std::normal_distribution<float> noise(0.0f, 0.01f);
  Image<float> depth(width, height);
  for (int v = 0; v < height; ++v) {
    for (int u = 0; u < width; ++u) depth(u, v) = (u < width / 2 ? 2.0f : 2.3f) + noise(rng);
  }
  for (int v = 10; v < 20; ++v) {
    for (int u = 5; u < 15; ++u) depth(u, v) = 0;
  }
  return depth;
}

double rms_error(const Image<float>& depth, int u0, int u1, float truth) {
  double sum = 0;
  int n = 0;
  for (int v = 0; v < depth.height; ++v) {
    for (int u = u0; u < u1; ++u) {
      if (depth(u, v) <= 0) continue;
      sum += std::pow(depth(u, v) - truth, 2);
      ++n;
    }
  }
  return std::sqrt(sum / n);
}

// Both forms of the filter, the paper's square window (the default) and the separable one, must do the job.
class BilateralForm : public ::testing::TestWithParam<bool> {
 protected:
  BilateralOptions options() const { return {.separable = GetParam()}; }
};

INSTANTIATE_TEST_SUITE_P(Forms, BilateralForm, ::testing::Bool(),
                         [](const ::testing::TestParamInfo<bool>& form) { return form.param ? "Separable" : "SquareWindow"; });

// The noisy step (noisy_step(64, 48, 3)) filtered: the noise within each side drops by more than
// `noise_factor`; right at the step no pixel is pulled towards the other side by more than 1.5 cm;
// holes stay holes and nothing else becomes one.
void expect_smoothed_step(const Image<float>& input, const Image<float>& output, double noise_factor) {
  EXPECT_LT(rms_error(output, 0, 30, 2.0f), rms_error(input, 0, 30, 2.0f) / noise_factor);
  EXPECT_LT(rms_error(output, 34, 64, 2.3f), rms_error(input, 34, 64, 2.3f) / noise_factor);
  for (int v = 0; v < 48; ++v) {
    EXPECT_LT(std::abs(output(31, v) - 2.0f), 0.015f + std::abs(input(31, v) - 2.0f)) << v;
    EXPECT_LT(std::abs(output(32, v) - 2.3f), 0.015f + std::abs(input(32, v) - 2.3f)) << v;
  }
  for (size_t i = 0; i < input.size(); ++i) EXPECT_EQ(output.data[i] == 0, input.data[i] == 0) << i;
}

TEST_P(BilateralForm, SmoothsSurfacesAndKeepsStepsAndHoles) {
  const Image<float> input = noisy_step(64, 48, 3);
  Image<float> output;
  bilateral_filter(input, BilateralKernel(options()), output, 2);
  // The paper's σ 4 px kernel averages ~100 pixels.
  expect_smoothed_step(input, output, 4);
}

TEST_P(BilateralForm, FlatSurfaceIsAFixedPoint) {
  Image<float> flat(20, 20, 1.5f);
  flat(3, 3) = 0;
  Image<float> output;
  bilateral_filter(flat, BilateralKernel(options()), output, 1);
  for (size_t i = 0; i < flat.size(); ++i) EXPECT_NEAR(output.data[i], flat.data[i], 1e-5f);  // float rounding: 10 µm
}

// One thread and two filter a noisy step to the same floats, bit for bit.
void expect_same_on_any_thread_count(const BilateralKernel& kernel) {
  const Image<float> input = noisy_step(50, 40, 9);
  Image<float> one, two;
  bilateral_filter(input, kernel, one, 1);
  bilateral_filter(input, kernel, two, 2);
  EXPECT_EQ(one, two);
}

TEST_P(BilateralForm, ThreadCountDoesNotChangeTheResult) {
  expect_same_on_any_thread_count(BilateralKernel(BilateralOptions{.spatial_sigma_px = 3, .radius_px = 4, .range_sigma_m = 0.03, .separable = GetParam()}));
}

// The vectorised row kernels form the same sums as the reference element function, pixel by pixel:
// the pair sums of the paper's 13×13 window, and the gathered taps of small windows (radius 1 and 2).
class BilateralRadius : public ::testing::TestWithParam<int> {};

INSTANTIATE_TEST_SUITE_P(Radii, BilateralRadius, ::testing::Values(1, 2, 3, 6));

TEST_P(BilateralRadius, RowKernelsMatchTheElementFunction) {
  const Image<float> input = noisy_step(70, 45, 5);
  const BilateralKernel kernel(BilateralOptions{.spatial_sigma_px = GetParam() <= 2 ? 1.0 : 4.0, .radius_px = GetParam()});
  Image<float> output;
  bilateral_filter(input, kernel, output, 2);
  for (int v = 0; v < input.height; ++v) {
    for (int u = 0; u < input.width; ++u) {
      EXPECT_NEAR(output(u, v), bilateral_pixel(u, v, input.data.data(), input.width, input.height, kernel), 1e-5f) << u << "," << v;
    }
  }
}

TEST_P(BilateralRadius, ThreadCountDoesNotChangeTheResult) {
  expect_same_on_any_thread_count(BilateralKernel(BilateralOptions{.spatial_sigma_px = 1.5, .radius_px = GetParam(), .range_sigma_m = 0.03}));
}

// The 5×5 window with σ 2 px (the small filter `zipfusion bench` compares) does the same job over
// fewer pixels: its weights average about 23 pixels' worth of independent noise, σ/4.8.
TEST(Bilateral, SmallWindowSmoothsSurfacesAndKeepsSteps) {
  const Image<float> input = noisy_step(64, 48, 3);
  Image<float> output;
  bilateral_filter(input, BilateralKernel(BilateralOptions{.spatial_sigma_px = 2, .radius_px = 2}), output, 2);
  expect_smoothed_step(input, output, 3);
}

// The range weight's polynomial exponential stays within 0.7 % of exp(−t) over the 3σ it covers.
TEST(Bilateral, RangeWeightFollowsTheGaussian) {
  for (float t = 0; t <= 4.5f; t += 0.01f) EXPECT_NEAR(exp_neg(t) / std::exp(-t), 1.0, 0.007) << t;
}

}  // namespace
}  // namespace zipfusion
