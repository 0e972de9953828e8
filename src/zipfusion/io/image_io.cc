#include "zipfusion/io/image_io.h"

#include <jpeglib.h>
#include <jerror.h>  // after jpeglib.h: the message codes (JWRN_…)
#include <png.h>

#include <csetjmp>
#include <cstdio>
#include <cstring>
#include <type_traits>
#include <opencv2/imgcodecs.hpp>

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

// Decoding goes to libpng and libjpeg directly rather than through cv::imdecode: OpenCV lets
// libjpeg print its warnings to stderr and decodes what it can of a corrupt or truncated JPEG
// ("Premature end of JPEG file", "Corrupt JPEG data"), so a cut-off colour frame came back as an
// image with grey rows and no error; and libpng printed its own lines before zipfusion's. Here
// every problem the libraries report, warnings about the pixels included, becomes one
// InvalidInput naming the file, and nothing is printed.

// Larger images than any depth camera's are refused before their pixels are allocated.
constexpr std::uint32_t kMostImageSide = 1 << 15;
constexpr std::uint64_t kMostImagePixels = std::uint64_t{1} << 26;

[[noreturn]] void throw_undecodable(const std::string& source, const char* problem) {
  throw InvalidInput(source + ": cannot decode image (corrupt or truncated): " + problem);
}

bool plausible_image_size(std::uint64_t width, std::uint64_t height) {
  return width > 0 && height > 0 && width <= kMostImageSide && height <= kMostImageSide && width * height <= kMostImagePixels;
}

void check_image_size(std::uint64_t width, std::uint64_t height, const std::string& source) {
  if (!plausible_image_size(width, height)) {
    throw InvalidInput(source + ": image size: " + std::to_string(width) + "x" + std::to_string(height) + " is not a plausible camera image");
  }
}

// libpng's callbacks: the bytes come from memory; an error records its message and jumps back to
// the setjmp in decode_png; warnings concern ancillary chunks, not the pixels, and are dropped.
struct PngSource {
  const std::uint8_t* data = nullptr;
  size_t size = 0;
  size_t offset = 0;
  const char* error = nullptr;
  char message[200] = {};
};

void png_read_bytes(png_structp png, png_bytep out, size_t length) {
  auto* source = static_cast<PngSource*>(png_get_io_ptr(png));
  if (length > source->size - source->offset) png_error(png, "the file ends early");
  std::memcpy(out, source->data + source->offset, length);
  source->offset += length;
}

void png_on_error(png_structp png, png_const_charp message) {
  auto* source = static_cast<PngSource*>(png_get_error_ptr(png));
  std::snprintf(source->message, sizeof source->message, "%s", message);
  source->error = source->message;
  png_longjmp(png, 1);
}

void png_on_warning(png_structp, png_const_charp) {}

// What decode_png reads besides the pixels. Every object with a destructor lives outside the
// setjmp's scope (a longjmp must skip none).
struct PngLayout {
  std::uint32_t width = 0, height = 0;
  std::vector<png_bytep> rows;
};

// Decodes a PNG straight into `image`: 16-bit grey (native byte order) for depth (a DepthImage),
// else 8-bit RGB (a ColorImage).
template <typename ImageT>
void decode_png(const std::vector<std::uint8_t>& bytes, const std::string& source, ImageT& image) {
  constexpr bool depth = std::is_same_v<ImageT, DepthImage>;
  PngLayout out;
  PngSource input{bytes.data(), bytes.size()};
  png_structp png = png_create_read_struct(PNG_LIBPNG_VER_STRING, &input, png_on_error, png_on_warning);
  if (png == nullptr) throw IoError(source + ": libpng could not start");
  png_infop info = png_create_info_struct(png);
  if (info == nullptr) {
    png_destroy_read_struct(&png, nullptr, nullptr);
    throw IoError(source + ": libpng could not start");
  }
  // What the file holds, when it is not what was asked for (set inside, thrown outside).
  int wrong_bits = 0, wrong_channels = 0;
  bool too_large = false;
  // setjmp alone in the condition, as C allows it.
  if (setjmp(png_jmpbuf(png)) == 0) {
    png_set_read_fn(png, &input, png_read_bytes);
    png_read_info(png, info);
    const int bit_depth = png_get_bit_depth(png, info), color_type = png_get_color_type(png, info);
    out.width = png_get_image_width(png, info);
    out.height = png_get_image_height(png, info);
    if (!plausible_image_size(out.width, out.height)) {
      too_large = true;
    } else if (depth) {
      if (bit_depth != 16 || color_type != PNG_COLOR_TYPE_GRAY) {
        wrong_bits = bit_depth;
        wrong_channels = png_get_channels(png, info);
      } else {
        png_set_swap(png);  // PNG stores 16-bit samples big-endian
      }
    } else if (bit_depth > 8) {
      wrong_bits = bit_depth;
      wrong_channels = png_get_channels(png, info);
    } else {
      png_set_expand(png);        // palette to RGB, grey below 8 bits to 8
      png_set_strip_alpha(png);
      png_set_gray_to_rgb(png);
    }
    if (wrong_bits == 0 && !too_large) {
      png_set_interlace_handling(png);
      png_read_update_info(png, info);
      const size_t row_bytes = png_get_rowbytes(png, info);
      if (row_bytes != static_cast<size_t>(out.width) * (depth ? 2 : 3)) png_error(png, "unexpected row layout");
      static_assert(sizeof(Rgb8) == 3 && sizeof(unsigned short) == 2);
      image = ImageT(static_cast<int>(out.width), static_cast<int>(out.height));
      out.rows.resize(out.height);
      auto* first = reinterpret_cast<std::uint8_t*>(image.data.data());
      for (std::uint32_t v = 0; v < out.height; ++v) out.rows[v] = first + v * row_bytes;
      png_read_image(png, out.rows.data());
      png_read_end(png, nullptr);
    }
  }
  png_destroy_read_struct(&png, &info, nullptr);
  if (input.error != nullptr) throw_undecodable(source, input.error);
  check_image_size(out.width, out.height, source);
  if (wrong_bits != 0) {
    throw InvalidInput(source + ": bit depth: " + (depth ? "depth PNG must be 16-bit single-channel" : "colour must be 8-bit") + ", got " +
                       std::to_string(wrong_bits) + "-bit with " + std::to_string(wrong_channels) + " channel(s)");
  }
}

// libjpeg's error manager: an error, and also a warning (libjpeg warns, and goes on with made-up
// pixels, where the data is corrupt or the file ends early), formats its message and jumps back.
struct JpegErrors {
  jpeg_error_mgr manager;
  std::jmp_buf jump;
  char message[JMSG_LENGTH_MAX];
};

[[noreturn]] void jpeg_on_error(j_common_ptr jpeg) {
  auto* errors = reinterpret_cast<JpegErrors*>(jpeg->err);
  (*jpeg->err->format_message)(jpeg, errors->message);
  std::longjmp(errors->jump, 1);
}

// A warning that the pixels are not what the camera recorded (the data ends early or is corrupt,
// and libjpeg fills in): an error. Warnings about the headers (a JFIF revision it does not know,
// bytes skipped before a marker, as some MJPEG cameras write) leave the pixels intact and pass.
void jpeg_on_message(j_common_ptr jpeg, int level) {
  if (level >= 0) return;
  switch (jpeg->err->msg_code) {
    case JWRN_JPEG_EOF:
    case JWRN_HIT_MARKER:
    case JWRN_MUST_RESYNC:
    case JWRN_HUFF_BAD_CODE:
    case JWRN_ARITH_BAD_CODE:
    case JWRN_BOGUS_PROGRESSION:
    case JWRN_NOT_SEQUENTIAL:
      jpeg_on_error(jpeg);
    default:
      return;
  }
}

void jpeg_no_output(j_common_ptr) {}

// Decodes a JPEG into `color` (resized to it).
void decode_jpeg(const std::vector<std::uint8_t>& bytes, const std::string& source, ColorImage& color) {
  jpeg_decompress_struct jpeg{};
  JpegErrors errors{};
  jpeg.err = jpeg_std_error(&errors.manager);
  errors.manager.error_exit = jpeg_on_error;
  errors.manager.emit_message = jpeg_on_message;
  errors.manager.output_message = jpeg_no_output;
  if (setjmp(errors.jump) != 0) {
    jpeg_destroy_decompress(&jpeg);
    throw_undecodable(source, errors.message);
  }
  jpeg_create_decompress(&jpeg);
  jpeg_mem_src(&jpeg, bytes.data(), static_cast<unsigned long>(bytes.size()));
  jpeg_read_header(&jpeg, TRUE);
  jpeg.out_color_space = JCS_RGB;  // grey JPEGs are expanded
  const bool cmyk = jpeg.jpeg_color_space == JCS_CMYK || jpeg.jpeg_color_space == JCS_YCCK;
  if (plausible_image_size(jpeg.image_width, jpeg.image_height) && !cmyk) {
    jpeg_start_decompress(&jpeg);
    color = ColorImage(static_cast<int>(jpeg.output_width), static_cast<int>(jpeg.output_height));
    static_assert(sizeof(Rgb8) == 3);
    while (jpeg.output_scanline < jpeg.output_height) {
      JSAMPROW row = reinterpret_cast<JSAMPROW>(color.data.data() + static_cast<size_t>(jpeg.output_scanline) * jpeg.output_width);
      jpeg_read_scanlines(&jpeg, &row, 1);
    }
    jpeg_finish_decompress(&jpeg);
  }
  const std::uint64_t width = jpeg.image_width, height = jpeg.image_height;
  jpeg_destroy_decompress(&jpeg);
  check_image_size(width, height, source);
  // Print colour separations, not a camera's image: libjpeg has no conversion to RGB.
  if (cmyk) throw InvalidInput(source + ": colour space: a CMYK JPEG is not a camera image (colour must be RGB or grey)");
}

}  // namespace

DepthImage decode_depth_png(const std::vector<std::uint8_t>& bytes, const std::string& source) {
  if (!is_png(bytes)) throw InvalidInput(source + ": not a PNG file (depth must be 16-bit PNG)");
  DepthImage depth;
  decode_png(bytes, source, depth);
  return depth;
}

DepthImage read_depth_png(const std::filesystem::path& path) {
  return decode_depth_png(read_file_bytes(path), path.string());
}

ColorImage decode_color_image(const std::vector<std::uint8_t>& bytes, const std::string& source) {
  if (is_jpeg(bytes)) {
    ColorImage color;
    decode_jpeg(bytes, source, color);
    return color;
  }
  if (!is_png(bytes)) throw InvalidInput(source + ": not a JPEG or PNG file");
  ColorImage color;
  decode_png(bytes, source, color);
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
