#include "zipfusion/io/image_io.h"

#include <jpeglib.h>
#include <jerror.h>  // after jpeglib.h: the message codes (JWRN_…)
#include <png.h>

#include <csetjmp>
#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <type_traits>
#include <opencv2/imgcodecs.hpp>

#include "zipfusion/core/error.h"
#include "zipfusion/io/file_util.h"

namespace zipfusion {
namespace {

constexpr std::uint8_t kPngSignature[8] = {0x89, 'P', 'N', 'G', '\r', '\n', 0x1a, '\n'};

bool is_png(std::span<const std::uint8_t> bytes) {
  return bytes.size() >= 8 && std::equal(kPngSignature, kPngSignature + 8, bytes.begin());
}

bool is_jpeg(std::span<const std::uint8_t> bytes) {
  return bytes.size() >= 3 && bytes[0] == 0xFF && bytes[1] == 0xD8 && bytes[2] == 0xFF;
}

// Decoding goes to libpng and libjpeg directly rather than through cv::imdecode: OpenCV lets
// libjpeg print its warnings to stderr and decodes what it can of a corrupt or truncated JPEG
// ("Premature end of JPEG file", "Corrupt JPEG data"), so a cut-off colour frame came back as an
// image with grey rows and no error; and libpng printed its own lines before zipfusion's. Here
// every problem the libraries report, warnings about the pixels included, becomes one
// CorruptFile naming the file, and nothing is printed.

[[noreturn]] void throw_undecodable(const std::string& source, const char* problem) {
  throw CorruptFile(source + ": cannot decode image (corrupt or truncated): " + problem);
}

}  // namespace

bool plausible_image_size(std::uint64_t width, std::uint64_t height) {
  return width > 0 && height > 0 && width <= kMostImageSide && height <= kMostImageSide && width * height <= kMostImagePixels;
}

namespace {

void check_image_size(std::uint64_t width, std::uint64_t height, const std::string& source) {
  if (!plausible_image_size(width, height)) {
    throw CorruptFile(source + ": image size: " + std::to_string(width) + "x" + std::to_string(height) + " is not a plausible camera image");
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

// libpng's memory (its allocator, png_create_read_struct_2), kept from image to image: libpng asks
// for the same few blocks for every image of a size (its two structs, a row or two, zlib's
// window), so after the first image each request finds a free block at least as large, and
// decoding allocates nothing. After each image the blocks it did not use are freed, so that images
// of changing sizes do not pile blocks up: what is kept is what the last image used. (Depth and
// colour each have their own, so that a camera's two images do not free each other's blocks.)
class PngMemory {
 public:
  PngMemory() { blocks_.reserve(32); }
  ~PngMemory() {
    for (const Block& block : blocks_) std::free(block.data);
  }
  PngMemory(const PngMemory&) = delete;
  PngMemory& operator=(const PngMemory&) = delete;

  // The smallest free block that holds `size` bytes, else a new one; null when out of memory
  // (libpng then reports the error). Never throws: it is called from inside libpng.
  void* allocate(size_t size) noexcept {
    Block* best = nullptr;
    for (Block& block : blocks_) {
      if (!block.used && block.size >= size && (best == nullptr || block.size < best->size)) best = &block;
    }
    if (best == nullptr) {
      void* data = std::malloc(size);
      if (data == nullptr) return nullptr;
      try {
        blocks_.push_back({data, size, false});
      } catch (...) {
        std::free(data);
        return nullptr;
      }
      best = &blocks_.back();
      ++blocks_made_;
    }
    best->used = best->touched = true;
    return best->data;
  }

  void release(void* data) noexcept {
    for (Block& block : blocks_) {
      if (block.data == data) {
        block.used = false;
        return;
      }
    }
  }

  // Frees the blocks not used since the last call (none is in use between images).
  void release_unused() noexcept {
    size_t kept = 0;
    for (Block& block : blocks_) {
      if (block.used || block.touched) {
        block.touched = false;
        blocks_[kept++] = block;
      } else {
        std::free(block.data);
      }
    }
    blocks_.resize(kept);
  }

  int blocks() const { return static_cast<int>(blocks_.size()); }
  long blocks_made() const { return blocks_made_; }

 private:
  struct Block {
    void* data = nullptr;
    size_t size = 0;
    bool used = false;     // handed to libpng and not yet given back
    bool touched = false;  // handed out since the last release_unused
  };
  std::vector<Block> blocks_;
  long blocks_made_ = 0;
};

png_voidp png_allocate(png_structp png, png_alloc_size_t size) { return static_cast<PngMemory*>(png_get_mem_ptr(png))->allocate(size); }

void png_release(png_structp png, png_voidp data) { static_cast<PngMemory*>(png_get_mem_ptr(png))->release(data); }

// Everything a PNG decode keeps, owned by decode_png: a longjmp from libpng back to the setjmp in
// read_png leaves that function's own locals indeterminate (C11 7.13.2.1), so read_png keeps none
// it reads after one, and skips no destructor. The destructor hands libpng's structs back however
// the decode ends, std::bad_alloc included.
struct PngDecode {
  PngSource input;
  png_structp png = nullptr;
  png_infop info = nullptr;
  std::uint32_t width = 0, height = 0;
  std::vector<png_bytep>* rows = nullptr;  // the decoder's, reused
  // What the file holds, when it is not what was asked for (set inside, thrown outside).
  int wrong_bits = 0, wrong_channels = 0;

  ~PngDecode() { png_destroy_read_struct(&png, &info, nullptr); }
};

// Reads the PNG of `d` into `image`: 16-bit grey (native byte order) for depth (a DepthImage),
// else 8-bit RGB (a ColorImage), in its buffer where that is large enough. False when libpng
// reported an error (d.input.error).
template <typename ImageT>
bool read_png(PngDecode& d, ImageT& image) {
  constexpr bool depth = std::is_same_v<ImageT, DepthImage>;
  // setjmp compared with a constant in the condition: one of the uses C allows (7.13.1.1).
  if (setjmp(png_jmpbuf(d.png)) != 0) return false;
  png_set_read_fn(d.png, &d.input, png_read_bytes);
  png_read_info(d.png, d.info);
  const int bit_depth = png_get_bit_depth(d.png, d.info), color_type = png_get_color_type(d.png, d.info);
  d.width = png_get_image_width(d.png, d.info);
  d.height = png_get_image_height(d.png, d.info);
  if (!plausible_image_size(d.width, d.height)) return true;  // decode_png names the size
  if (depth) {
    if (bit_depth != 16 || color_type != PNG_COLOR_TYPE_GRAY) {
      d.wrong_bits = bit_depth;
      d.wrong_channels = png_get_channels(d.png, d.info);
      return true;
    }
    png_set_swap(d.png);  // PNG stores 16-bit samples big-endian
  } else if (bit_depth > 8) {
    d.wrong_bits = bit_depth;
    d.wrong_channels = png_get_channels(d.png, d.info);
    return true;
  } else {
    png_set_expand(d.png);        // palette to RGB, grey below 8 bits to 8
    png_set_strip_alpha(d.png);
    png_set_gray_to_rgb(d.png);
  }
  png_set_interlace_handling(d.png);
  png_read_update_info(d.png, d.info);
  const size_t row_bytes = png_get_rowbytes(d.png, d.info);
  if (row_bytes != static_cast<size_t>(d.width) * (depth ? 2 : 3)) png_error(d.png, "unexpected row layout");
  static_assert(sizeof(Rgb8) == 3 && sizeof(unsigned short) == 2);
  image.resize_for_overwrite(static_cast<int>(d.width), static_cast<int>(d.height));
  d.rows->resize(d.height);
  auto* first = reinterpret_cast<std::uint8_t*>(image.data.data());
  for (std::uint32_t v = 0; v < d.height; ++v) (*d.rows)[v] = first + v * row_bytes;
  png_read_image(d.png, d.rows->data());
  png_read_end(d.png, nullptr);
  return true;
}

// Decodes a PNG straight into `image` (see read_png), libpng's memory from `memory`.
template <typename ImageT>
void decode_png(std::span<const std::uint8_t> bytes, const std::string& source, ImageT& image, PngMemory& memory,
                std::vector<png_bytep>& rows) {
  constexpr bool depth = std::is_same_v<ImageT, DepthImage>;
  struct ReleaseUnused {  // after libpng's structs have gone back (d's destructor), however it ends
    PngMemory& memory;
    ~ReleaseUnused() { memory.release_unused(); }
  } release_unused{memory};
  PngDecode d;
  d.input = PngSource{bytes.data(), bytes.size()};
  d.rows = &rows;
  d.png = png_create_read_struct_2(PNG_LIBPNG_VER_STRING, &d.input, png_on_error, png_on_warning, &memory, png_allocate, png_release);
  if (d.png == nullptr) throw IoError(source + ": libpng could not start");
  d.info = png_create_info_struct(d.png);
  if (d.info == nullptr) throw IoError(source + ": libpng could not start");
  if (!read_png(d, image)) throw_undecodable(source, d.input.error);
  check_image_size(d.width, d.height, source);
  if (d.wrong_bits != 0) {
    throw InvalidInput(source + ": bit depth: " + (depth ? "depth PNG must be 16-bit single-channel" : "colour must be 8-bit") + ", got " +
                       std::to_string(d.wrong_bits) + "-bit with " + std::to_string(d.wrong_channels) + " channel(s)");
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

// Everything a JPEG decode keeps, owned by decode_jpeg (as PngDecode, for the same reasons).
// libjpeg's destroy is a no-op on the zeroed struct, so the destructor needs no flag. A new
// decompressor for every image: libjpeg keeps the Huffman and quantisation tables an image
// defines for the next (abbreviated streams), so a kept one decoded an image without its own
// tables (MJPEG's, which rely on the standard ones) through the last image's: other pixels, or
// "bad Huffman code" (found by the fuzz target's kept decoder).
struct JpegDecode {
  jpeg_decompress_struct jpeg{};
  JpegErrors errors{};

  ~JpegDecode() { jpeg_destroy_decompress(&jpeg); }
};

// Print colour separations, not a camera's image: libjpeg has no conversion to RGB.
bool is_cmyk(const jpeg_decompress_struct& jpeg) { return jpeg.jpeg_color_space == JCS_CMYK || jpeg.jpeg_color_space == JCS_YCCK; }

// Reads the JPEG `bytes` into `color` (resized to it, its buffer reused). False when libjpeg
// reported an error (d.errors.message).
bool read_jpeg(JpegDecode& d, std::span<const std::uint8_t> bytes, ColorImage& color) {
  if (setjmp(d.errors.jump) != 0) return false;
  jpeg_create_decompress(&d.jpeg);
  jpeg_mem_src(&d.jpeg, bytes.data(), static_cast<unsigned long>(bytes.size()));
  jpeg_read_header(&d.jpeg, TRUE);
  d.jpeg.out_color_space = JCS_RGB;  // grey JPEGs are expanded
  if (!plausible_image_size(d.jpeg.image_width, d.jpeg.image_height) || is_cmyk(d.jpeg)) return true;  // decode_jpeg names either
  jpeg_start_decompress(&d.jpeg);
  color.resize_for_overwrite(static_cast<int>(d.jpeg.output_width), static_cast<int>(d.jpeg.output_height));
  static_assert(sizeof(Rgb8) == 3);
  while (d.jpeg.output_scanline < d.jpeg.output_height) {
    JSAMPROW row = reinterpret_cast<JSAMPROW>(color.data.data() + static_cast<size_t>(d.jpeg.output_scanline) * d.jpeg.output_width);
    jpeg_read_scanlines(&d.jpeg, &row, 1);
  }
  jpeg_finish_decompress(&d.jpeg);
  return true;
}

void decode_jpeg(std::span<const std::uint8_t> bytes, const std::string& source, ColorImage& color) {
  JpegDecode d;
  d.jpeg.err = jpeg_std_error(&d.errors.manager);
  d.errors.manager.error_exit = jpeg_on_error;
  d.errors.manager.emit_message = jpeg_on_message;
  d.errors.manager.output_message = jpeg_no_output;
  if (!read_jpeg(d, bytes, color)) throw_undecodable(source, d.errors.message);
  check_image_size(d.jpeg.image_width, d.jpeg.image_height, source);
  if (is_cmyk(d.jpeg)) throw InvalidInput(source + ": colour space: a CMYK JPEG is not a camera image (colour must be RGB or grey)");
}

}  // namespace

struct ImageDecoder::Libraries {
  std::vector<std::uint8_t> bytes;  // the last file's
  PngMemory depth_png_memory, color_png_memory;
  std::vector<png_bytep> png_rows;
};

ImageDecoder::ImageDecoder() : libraries_(std::make_unique<Libraries>()) {}
ImageDecoder::~ImageDecoder() = default;
ImageDecoder::ImageDecoder(ImageDecoder&&) noexcept = default;
ImageDecoder& ImageDecoder::operator=(ImageDecoder&&) noexcept = default;

void ImageDecoder::decode_depth_png(std::span<const std::uint8_t> bytes, const std::string& source, DepthImage& depth) {
  if (!is_png(bytes)) throw CorruptFile(source + ": not a PNG file (depth must be 16-bit PNG)");
  decode_png(bytes, source, depth, libraries_->depth_png_memory, libraries_->png_rows);
}

void ImageDecoder::decode_color_image(std::span<const std::uint8_t> bytes, const std::string& source, ColorImage& color) {
  if (is_jpeg(bytes)) return decode_jpeg(bytes, source, color);
  if (!is_png(bytes)) throw CorruptFile(source + ": not a JPEG or PNG file");
  decode_png(bytes, source, color, libraries_->color_png_memory, libraries_->png_rows);
}

void ImageDecoder::read_depth_png(const std::string& path, DepthImage& depth) {
  read_file_bytes(path, libraries_->bytes);
  decode_depth_png(libraries_->bytes, path, depth);
}

void ImageDecoder::read_color_image(const std::string& path, ColorImage& color) {
  read_file_bytes(path, libraries_->bytes);
  decode_color_image(libraries_->bytes, path, color);
}

int ImageDecoder::png_memory_blocks() const { return libraries_->depth_png_memory.blocks() + libraries_->color_png_memory.blocks(); }

long ImageDecoder::png_blocks_made() const { return libraries_->depth_png_memory.blocks_made() + libraries_->color_png_memory.blocks_made(); }

DepthImage decode_depth_png(std::span<const std::uint8_t> bytes, const std::string& source) {
  DepthImage depth;
  ImageDecoder().decode_depth_png(bytes, source, depth);
  return depth;
}

DepthImage read_depth_png(const std::filesystem::path& path) {
  DepthImage depth;
  ImageDecoder().read_depth_png(path.string(), depth);
  return depth;
}

ColorImage decode_color_image(std::span<const std::uint8_t> bytes, const std::string& source) {
  ColorImage color;
  ImageDecoder().decode_color_image(bytes, source, color);
  return color;
}

ColorImage read_color_image(const std::filesystem::path& path) {
  ColorImage color;
  ImageDecoder().read_color_image(path.string(), color);
  return color;
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
