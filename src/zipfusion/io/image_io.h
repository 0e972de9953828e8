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
#include <memory>
#include <optional>
#include <span>
#include <string>
#include <vector>

#include "zipfusion/core/error.h"
#include "zipfusion/core/image.h"

namespace zipfusion {

//! Larger images than any depth camera's are refused, as files before their pixels are allocated
//! and as rig.json intrinsics: at most 32768 pixels a side and 2^26 pixels.
constexpr std::uint32_t kMostImageSide = 1 << 15;
constexpr std::uint64_t kMostImagePixels = std::uint64_t{1} << 26;
bool plausible_image_size(std::uint64_t width, std::uint64_t height);

//! Decodes a 16-bit single-channel PNG. `source` names the file in errors.
DepthImage decode_depth_png(std::span<const std::uint8_t> bytes, const std::string& source);
DepthImage read_depth_png(const std::filesystem::path& path);

//! Decodes an 8-bit colour JPEG or PNG (grey images are expanded to RGB).
ColorImage decode_color_image(std::span<const std::uint8_t> bytes, const std::string& source);
ColorImage read_color_image(const std::filesystem::path& path);

//! Decodes image after image into the same images, the frames of a capture, with the functions
//! above's checks and errors: once its buffers and the images' have grown to the images' sizes,
//! it allocates nothing from the C++ heap, and libpng nothing at all (libpng is handed blocks
//! that it finds again at the next image of the kind, depth or colour; those an image did not use
//! are freed). It keeps between images the file's bytes and libpng's memory and row table.
//! libjpeg gets a new decompressor for each image (a kept one carries an image's tables to the
//! next) and takes and frees its memory with malloc: it has no allocator to hand it. On an error
//! the image's pixels are unspecified. One per thread: not thread-safe; a moved-from decoder may
//! only be assigned to or destroyed.
class ImageDecoder {
 public:
  ImageDecoder();
  ~ImageDecoder();
  ImageDecoder(const ImageDecoder&) = delete;
  ImageDecoder& operator=(const ImageDecoder&) = delete;
  ImageDecoder(ImageDecoder&&) noexcept;
  ImageDecoder& operator=(ImageDecoder&&) noexcept;

  void decode_depth_png(std::span<const std::uint8_t> bytes, const std::string& source, DepthImage& depth);
  void decode_color_image(std::span<const std::uint8_t> bytes, const std::string& source, ColorImage& color);
  //! read_file_bytes into the decoder's buffer, then decode; `path` names the file in errors.
  void read_depth_png(const std::string& path, DepthImage& depth);
  void read_color_image(const std::string& path, ColorImage& color);

  //! Blocks of memory kept for libpng now: those the last image of each kind used.
  int png_memory_blocks() const;
  //! Blocks made for libpng so far (malloc calls): this stops growing once the images' sizes do.
  long png_blocks_made() const;

 private:
  struct Libraries;
  std::unique_ptr<Libraries> libraries_;
};

//! Calls `read` (which reads and decodes a file); where the file's bytes cannot be read or decoded
//! (IoError, CorruptFile) returns the error's message, naming the file, instead of throwing. Every
//! other error goes up: an image that decodes but breaks the format's promise is not bad data.
template <typename Read>
std::optional<std::string> undecodable_reason(Read&& read) {
  try {
    read();
  } catch (const CorruptFile& e) {
    return e.what();
  } catch (const IoError& e) {
    return e.what();
  }
  return std::nullopt;
}

std::vector<std::uint8_t> encode_depth_png(const DepthImage& depth);
//! Encodes as JPEG (quality 1..100) or PNG, chosen by `extension` (".jpg", ".jpeg" or ".png").
std::vector<std::uint8_t> encode_color_image(const ColorImage& color, const std::string& extension,
                                             int jpeg_quality = 90);

//! Atomic writers (temporary file + rename).
void write_depth_png(const std::filesystem::path& path, const DepthImage& depth);
void write_color_image(const std::filesystem::path& path, const ColorImage& color, int jpeg_quality = 90);

}  // namespace zipfusion
