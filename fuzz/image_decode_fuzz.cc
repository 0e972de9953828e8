// libFuzzer target: depth PNGs and colour PNG/JPEG images (io/image_io.h), the bytes of every
// frame file a capture holds. A decoded image must be whole and survive a lossless round trip. A
// refusal must be a CorruptFile (which a capture's reader leaves out, as a missing frame) unless
// the image decoded but is not what the format promises (bit depth, colour space), which stops a
// run: corrupt bytes must never do that. One ImageDecoder, kept from input to input as a capture's
// reader keeps it from frame to frame, must give what a fresh one gives, whatever the inputs
// before it left in it (libjpeg after an error, libpng's blocks, a larger image's buffer).

#include <cstddef>
#include <cstdint>
#include <exception>
#include <optional>
#include <string>
#include <vector>

#include "fuzz/fuzz_check.h"
#include "zipfusion/io/image_io.h"

namespace zipfusion::fuzz {
namespace {

template <class Decode>
auto decoded_or_corrupt(const char* decoder, Decode decode) {
  return decoded_or_error(decoder, [&] {
    try {
      return decode();
    } catch (const CorruptFile&) {
      throw;
    } catch (const InvalidInput& e) {
      const std::string message = e.what();
      if (message.find(": bit depth: ") == std::string::npos && message.find(": colour space: ") == std::string::npos) {
        fail("a refusal that is not a CorruptFile: " + message);
      }
      throw;
    }
  });
}

template <class T>
void check_shape(const Image<T>& image) {
  if (image.width <= 0 || image.height <= 0) fail("an empty image was returned");
  if (image.data.size() != static_cast<size_t>(image.width) * image.height) fail("pixels do not fill the image");
}

// The outcome of `decode`: the error's message, or empty (then `image` holds the pixels).
template <class Decode>
std::string error_of(Decode decode) {
  try {
    decode();
  } catch (const std::exception& e) {
    return e.what();
  }
  return {};
}

ImageDecoder& kept_decoder() {
  static ImageDecoder decoder;
  return decoder;
}

// The kept decoder's outcome against the fresh one's (`fresh`: the image, or none after an error).
template <class ImageT, class Decode>
void check_kept_decoder(const std::optional<ImageT>& fresh, Decode decode_into) {
  static ImageT image;
  const std::string error = error_of([&] { decode_into(image); });
  if (fresh.has_value() != error.empty()) fail("a kept decoder " + (error.empty() ? std::string("decoded what a fresh one refused") : "refused what a fresh one decoded: " + error));
  if (fresh && !(image == *fresh)) fail("a kept decoder decoded other pixels than a fresh one");
}

void check_depth(const std::vector<std::uint8_t>& bytes) {
  const auto depth = decoded_or_corrupt("depth", [&] { return decode_depth_png(bytes, kSource); });
  check_kept_decoder(depth, [&](DepthImage& image) { kept_decoder().decode_depth_png(bytes, kSource, image); });
  if (!depth) return;
  check_shape(*depth);
  const DepthImage again = must_decode([&] { return decode_depth_png(encode_depth_png(*depth), kSource); }, "depth PNG");
  if (!(again == *depth)) fail("depth PNG round trip changed the image");
}

void check_color(const std::vector<std::uint8_t>& bytes) {
  const auto color = decoded_or_corrupt("color", [&] { return decode_color_image(bytes, kSource); });
  check_kept_decoder(color, [&](ColorImage& image) { kept_decoder().decode_color_image(bytes, kSource, image); });
  if (!color) return;
  check_shape(*color);
  const ColorImage again = must_decode([&] { return decode_color_image(encode_color_image(*color, ".png"), kSource); }, "colour PNG");
  if (!(again == *color)) fail("colour PNG round trip changed the image");
}

}  // namespace
}  // namespace zipfusion::fuzz

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
  const std::vector<std::uint8_t> bytes(data, data + size);
  zipfusion::fuzz::check_depth(bytes);
  zipfusion::fuzz::check_color(bytes);
  return 0;
}
