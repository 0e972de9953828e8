#pragma once
//! \file
//! Depth and colour image files of a rig capture, decoded by libpng and libjpeg and encoded by
//! OpenCV. Decoding throws, naming the file: CorruptFile (an InvalidInput) for bytes that do not
//! decode (not the format, corrupt, truncated, even where the library could make up the missing
//! pixels, or a size no camera has); plain InvalidInput for an image that decodes but is not what
//! the capture format promises (depth not 16-bit single-channel, colour not 8-bit, a CMYK JPEG);
//! IoError when the file cannot be read. Capture::load_camera_frame leaves out the first and the
//! last and stops at the second. It never prints.

#include <cstdint>
#include <filesystem>
#include <functional>
#include <optional>
#include <string>
#include <vector>

#include "zipfusion/core/image.h"

namespace zipfusion {

//! Larger images than any depth camera's are refused, as files before their pixels are allocated
//! and as rig.json intrinsics: at most 32768 pixels a side and 2^26 pixels.
constexpr std::uint32_t kMostImageSide = 1 << 15;
constexpr std::uint64_t kMostImagePixels = std::uint64_t{1} << 26;
bool plausible_image_size(std::uint64_t width, std::uint64_t height);

//! Decodes a 16-bit single-channel PNG. `source` names the file in errors.
DepthImage decode_depth_png(const std::vector<std::uint8_t>& bytes, const std::string& source);
DepthImage read_depth_png(const std::filesystem::path& path);

//! Decodes an 8-bit colour JPEG or PNG (grey images are expanded to RGB).
ColorImage decode_color_image(const std::vector<std::uint8_t>& bytes, const std::string& source);
ColorImage read_color_image(const std::filesystem::path& path);

//! Calls `read` (which reads and decodes a file); where the file's bytes cannot be read or decoded
//! (IoError, CorruptFile) returns the error's message, naming the file, instead of throwing. Every
//! other error goes up: an image that decodes but breaks the format's promise is not bad data.
std::optional<std::string> undecodable_reason(const std::function<void()>& read);

std::vector<std::uint8_t> encode_depth_png(const DepthImage& depth);
//! Encodes as JPEG (quality 1..100) or PNG, chosen by `extension` (".jpg", ".jpeg" or ".png").
std::vector<std::uint8_t> encode_color_image(const ColorImage& color, const std::string& extension,
                                             int jpeg_quality = 90);

//! Atomic writers (temporary file + rename).
void write_depth_png(const std::filesystem::path& path, const DepthImage& depth);
void write_color_image(const std::filesystem::path& path, const ColorImage& color, int jpeg_quality = 90);

}  // namespace zipfusion
