#include "zipfusion/calib/led_detection.h"

#include <algorithm>
#include <array>
#include <vector>
#include <opencv2/imgproc.hpp>
#include <string>

#include "zipfusion/core/error.h"

namespace zipfusion {
namespace {

// How far pixel p's channel `c` rises above the brighter of the other two.
inline int dominance_margin(const Rgb8& p, int c) {
  const int v[3] = {p.r, p.g, p.b};
  return v[c] - std::max(v[(c + 1) % 3], v[(c + 2) % 3]);
}

inline bool is_led_pixel(const Rgb8& p, int c, const LedDetectionOptions& o) {
  const int v[3] = {p.r, p.g, p.b};
  return v[c] >= o.min_level && v[c] >= o.min_dominance * std::max(v[(c + 1) % 3], v[(c + 2) % 3]);
}

// Weighted centroid over the blob's box grown by 2 px: the glow's tails below the threshold still
// weigh in, symmetrically, so the estimate is not pulled by the threshold's cut. A saturated core
// weighs less than its rim (its other channels saturate too), which keeps the weights symmetric.
Eigen::Vector2d weighted_centroid(const ColorImage& image, int channel, const cv::Rect& box, double floor) {
  const int x0 = std::max(0, box.x - 2), y0 = std::max(0, box.y - 2);
  const int x1 = std::min(image.width - 1, box.x + box.width + 1), y1 = std::min(image.height - 1, box.y + box.height + 1);
  double sum = 0, su = 0, sv = 0;
  for (int v = y0; v <= y1; ++v) {
    for (int u = x0; u <= x1; ++u) {
      const double w = std::max(0.0, dominance_margin(image(u, v), channel) - floor);
      sum += w;
      su += w * u;
      sv += w * v;
    }
  }
  if (sum <= 0) return {box.x + (box.width - 1) / 2.0, box.y + (box.height - 1) / 2.0};
  return {su / sum, sv / sum};
}

}  // namespace

void LedDetectionOptions::validate() const {
  auto fail = [](const std::string& field, const std::string& problem) { throw InvalidInput(field + ": " + problem); };
  if (min_level < 1 || min_level > 255) fail("min_level", "must be in [1, 255]");
  if (min_contrast < 0 || min_contrast > 254) fail("min_contrast", "must be in [0, 254]");
  if (!(min_dominance >= 1 && min_dominance < 50)) fail("min_dominance", "must be in [1, 50)");
  if (min_area_px < 1 || max_area_px < min_area_px) fail("min_area_px", "need 1 <= min_area_px <= max_area_px");
  if (!(min_fill > 0 && min_fill <= 1)) fail("min_fill", "must be in (0, 1]");
  if (!(min_colored_share > 0 && min_colored_share <= 1)) fail("min_colored_share", "must be in (0, 1]");
  if (!(max_aspect >= 1)) fail("max_aspect", "must be >= 1");
  if (!(weight_floor >= 0 && weight_floor < 255)) fail("weight_floor", "must be in [0, 255)");
  if (!(min_separation_px >= 0)) fail("min_separation_px", "must be >= 0");
}

WandDetection detect_wand_leds(const ColorImage& image, const LedDetectionOptions& o) {
  // Bright blobs first, whatever their colour (a saturated LED core is nearly white), then each
  // blob's colour from the share of its pixels where red or green clearly dominates.
  // In a lit room the threshold rises with the room: the median brightness (every 4th pixel's
  // brightest channel) plus min_contrast.
  std::array<int, 256> histogram{};
  int samples = 0;
  for (size_t i = 0; i < image.data.size(); i += 4, ++samples) {
    const Rgb8& p = image.data[i];
    ++histogram[std::max({p.r, p.g, p.b})];
  }
  int median = 0;
  for (int seen = 0; median < 255 && (seen += histogram[median]) < samples / 2;) ++median;
  const int level = std::max(o.min_level, median + o.min_contrast);
  cv::Mat bright(image.height, image.width, CV_8U);
  for (int v = 0; v < image.height; ++v) {
    unsigned char* row = bright.ptr<unsigned char>(v);
    for (int u = 0; u < image.width; ++u) {
      const Rgb8& p = image(u, v);
      row[u] = std::max({p.r, p.g, p.b}) >= level ? 255 : 0;
    }
  }
  cv::Mat labels, stats, centroids;
  const int count = cv::connectedComponentsWithStats(bright, labels, stats, centroids, 8, CV_32S);
  std::vector<std::array<int, 2>> dominated(count, {0, 0});  // [blob][red, green] pixels
  for (int v = 0; v < image.height; ++v) {
    const int* row = labels.ptr<int>(v);
    for (int u = 0; u < image.width; ++u) {
      if (row[u] == 0) continue;
      for (int c = 0; c < 2; ++c) dominated[row[u]][c] += is_led_pixel(image(u, v), c, o);
    }
  }
  WandDetection d;
  LedSpot* spots[2] = {&d.red, &d.green};
  cv::Rect chosen[2];
  for (int i = 1; i < count; ++i) {
    const int area = stats.at<int>(i, cv::CC_STAT_AREA);
    const int w = stats.at<int>(i, cv::CC_STAT_WIDTH), h = stats.at<int>(i, cv::CC_STAT_HEIGHT);
    if (area < o.min_area_px || area > o.max_area_px) continue;
    if (static_cast<double>(area) / (w * h) < o.min_fill) continue;
    if (static_cast<double>(std::max(w, h)) / std::min(w, h) > o.max_aspect) continue;
    for (int c = 0; c < 2; ++c) {
      // Mostly this colour, hardly the other (a red and a green LED merged into one blob is neither).
      if (dominated[i][c] < o.min_colored_share * area || dominated[i][1 - c] * 4 > dominated[i][c]) continue;
      ++spots[c]->candidates;
      chosen[c] = cv::Rect(stats.at<int>(i, cv::CC_STAT_LEFT), stats.at<int>(i, cv::CC_STAT_TOP), w, h);
    }
  }
  for (int c = 0; c < 2; ++c) {
    LedSpot& spot = *spots[c];
    if (spot.candidates != 1) {
      spot.status = spot.candidates == 0 ? LedStatus::kMissing : LedStatus::kAmbiguous;
      continue;
    }
    spot.status = LedStatus::kFound;
    spot.pixel = weighted_centroid(image, c, chosen[c], o.weight_floor);
  }
  if (d.red.status == LedStatus::kFound && d.green.status == LedStatus::kFound) {
    d.overlapping = (d.red.pixel - d.green.pixel).norm() < o.min_separation_px;
  }
  return d;
}

}  // namespace zipfusion
