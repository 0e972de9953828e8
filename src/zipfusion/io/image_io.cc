#include "zipfusion/io/image_io.h"

#include <opencv2/imgcodecs.hpp>
#include <opencv2/imgproc.hpp>

#include "zipfusion/core/error.h"
#include "zipfusion/io/file_util.h"

namespace zipfusion {
namespace {

constexpr std::uint8_t kPngSignature[8] = {0x89, 'P', 'N', 'G', '\r', '\n', 0x1a, '\n'};

bool is_png(const std::vector<std::uint8_t>& bytes) {
  return bytes.size() >= 8 && std::equal(kPngSignature, kPngSignature + 8, bytes.begin());
}

bool is_jpeg(const std::vector<std::uint8_t>& bytes) {
  return bytes.size() >= 3 && bytes[0] == 0xFF && bytes[1] == 0xD8 && bytes[2] == 0xFF;
}

cv::Mat decode(const std::vector<std::uint8_t>& bytes, int flags, const std::string& source) {
  cv::Mat image;
  try {
    image = cv::imdecode(cv::Mat(1, static_cast<int>(bytes.size()), CV_8UC1, const_cast<std::uint8_t*>(bytes.data())), flags);
  } catch (const cv::Exception&) {
    image.release();
  }
  if (image.empty()) throw InvalidInput(source + ": cannot decode image (corrupt or truncated)");
  return image;
}

std::string describe(const cv::Mat& m) {
  const int bits = m.depth() == CV_16U ? 16 : m.depth() == CV_8U ? 8 : 32;
  return std::to_string(bits) + "-bit with " + std::to_string(m.channels()) + " channel(s)";
}

}  // namespace

DepthImage decode_depth_png(const std::vector<std::uint8_t>& bytes, const std::string& source) {
  if (!is_png(bytes)) throw InvalidInput(source + ": not a PNG file (depth must be 16-bit PNG)");
  const cv::Mat m = decode(bytes, cv::IMREAD_UNCHANGED, source);
  if (m.depth() != CV_16U || m.channels() != 1) {
    throw InvalidInput(source + ": bit depth: depth PNG must be 16-bit single-channel, got " + describe(m));
  }
  DepthImage depth(m.cols, m.rows);
  for (int v = 0; v < m.rows; ++v) {
    const auto* row = m.ptr<std::uint16_t>(v);
    std::copy(row, row + m.cols, depth.data.begin() + static_cast<size_t>(v) * m.cols);
  }
  return depth;
}

DepthImage read_depth_png(const std::filesystem::path& path) {
  return decode_depth_png(read_file_bytes(path), path.string());
}

ColorImage decode_color_image(const std::vector<std::uint8_t>& bytes, const std::string& source) {
  if (!is_png(bytes) && !is_jpeg(bytes)) throw InvalidInput(source + ": not a JPEG or PNG file");
  cv::Mat m = decode(bytes, cv::IMREAD_UNCHANGED, source);
  if (m.depth() != CV_8U) {
    throw InvalidInput(source + ": bit depth: colour must be 8-bit, got " + describe(m));
  }
  int conversion = 0;
  switch (m.channels()) {
    case 1: conversion = cv::COLOR_GRAY2RGB; break;
    case 3: conversion = cv::COLOR_BGR2RGB; break;
    case 4: conversion = cv::COLOR_BGRA2RGB; break;
    default: throw InvalidInput(source + ": colour image has " + std::to_string(m.channels()) + " channels");
  }
  // Converted straight into the image's pixels (Rgb8 is three packed bytes, as CV_8UC3): no
  // intermediate image and no copy of it.
  static_assert(sizeof(Rgb8) == 3);
  ColorImage color(m.cols, m.rows);
  cv::Mat rgb(m.rows, m.cols, CV_8UC3, color.data.data());
  cv::cvtColor(m, rgb, conversion);
  return color;
}

ColorImage read_color_image(const std::filesystem::path& path) {
  return decode_color_image(read_file_bytes(path), path.string());
}

std::vector<std::uint8_t> encode_depth_png(const DepthImage& depth) {
  const cv::Mat m(depth.height, depth.width, CV_16UC1, const_cast<unsigned short*>(depth.data.data()));
  std::vector<std::uint8_t> bytes;
  // Compression 1: depth maps are written every frame; level 1 is several times faster than the
  // default and only slightly larger.
  if (!cv::imencode(".png", m, bytes, {cv::IMWRITE_PNG_COMPRESSION, 1})) throw IoError("PNG encoding failed");
  return bytes;
}

std::vector<std::uint8_t> encode_color_image(const ColorImage& color, const std::string& extension, int jpeg_quality) {
  cv::Mat bgr(color.height, color.width, CV_8UC3);
  for (int v = 0; v < color.height; ++v) {
    auto* row = bgr.ptr<cv::Vec3b>(v);
    for (int u = 0; u < color.width; ++u) {
      const Rgb8 c = color(u, v);
      row[u] = {c.b, c.g, c.r};
    }
  }
  std::vector<std::uint8_t> bytes;
  const bool is_jpeg_ext = extension == ".jpg" || extension == ".jpeg";
  if (!is_jpeg_ext && extension != ".png") throw InvalidInput("colour image extension must be .jpg or .png, got " + extension);
  const std::vector<int> params =
      is_jpeg_ext ? std::vector<int>{cv::IMWRITE_JPEG_QUALITY, jpeg_quality} : std::vector<int>{cv::IMWRITE_PNG_COMPRESSION, 1};
  if (!cv::imencode(extension, bgr, bytes, params)) throw IoError("image encoding failed");
  return bytes;
}

void write_depth_png(const std::filesystem::path& path, const DepthImage& depth) {
  write_file_atomic(path, encode_depth_png(depth));
}

void write_color_image(const std::filesystem::path& path, const ColorImage& color, int jpeg_quality) {
  write_file_atomic(path, encode_color_image(color, path.extension().string(), jpeg_quality));
}

}  // namespace zipfusion
