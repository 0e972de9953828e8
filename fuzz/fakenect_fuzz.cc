// libFuzzer target: fakenect dumps (live/fakenect_dump.h), which `record --replay` and
// `serve --live --replay` read: INDEX.txt and the PGM depth / PPM colour frames. Whatever is
// accepted must come back unchanged from the writers (an INDEX.txt entry from the name the
// recorder would give it), and decoding into images kept from earlier inputs must give what fresh
// images give.

#include <cmath>
#include <cstddef>
#include <cstdint>
#include <limits>
#include <optional>
#include <span>
#include <string>

#include "fuzz/fuzz_check.h"
#include "zipfusion/live/fakenect_dump.h"

namespace zipfusion::fuzz {
namespace {

void check_index(const std::string& text) {
  const auto entries = decoded_or_error("index", [&] { return parse_fakenect_index(text, kSource); });
  if (!entries) return;
  for (const FakenectIndexEntry& e : *entries) {
    if (!(e.time_s >= 0 && e.time_s <= 1e10)) fail("an entry time outside [0, 1e10] s: " + e.file);
    // The name the recorder gives the same entry must parse back to it, its time to the
    // microseconds that %f keeps (and the double's own rounding).
    const std::string name = fakenect_file_name(e.type, e.time_s, e.timestamp);
    const auto again = must_decode([&] { return parse_fakenect_index(name + "\n", kSource); }, "INDEX.txt");
    const double printed_precision = 5e-7 + 2 * e.time_s * std::numeric_limits<double>::epsilon();
    if (again.size() != 1 || again[0].type != e.type || again[0].timestamp != e.timestamp || std::abs(again[0].time_s - e.time_s) > printed_precision) {
      fail("INDEX.txt entry does not survive its own file name: " + e.file + " as " + name);
    }
  }
}

// Decoding into an image kept from the inputs before (as a replay does, frame after frame) gives
// what a fresh image gives, and refuses what it refuses.
template <typename ImageT, typename DecodeInto>
void check_kept(std::span<const std::uint8_t> bytes, const std::optional<ImageT>& fresh, ImageT& kept, DecodeInto decode_into) {
  bool refused = false;
  try {
    decode_into(bytes, kSource, kept);
  } catch (const InvalidInput&) {
    refused = true;
  }
  if (refused != !fresh) fail(refused ? "a kept image refused what a fresh one decodes" : "a kept image decoded what a fresh one refuses");
  if (fresh && !(kept == *fresh)) fail("decoding into a kept image gave another image than a fresh one");
}

RawDepthImage kept_depth;  // across inputs, as ReplayCamera keeps its buffers
ColorImage kept_color;

void check_depth(std::span<const std::uint8_t> bytes) {
  const auto raw = decoded_or_error("depth", [&] { return decode_fakenect_depth(bytes, kSource); });
  check_kept(bytes, raw, kept_depth, [](auto b, const std::string& s, RawDepthImage& out) { decode_fakenect_depth(b, s, out); });
  if (!raw) return;
  for (const std::uint16_t d : raw->data) {
    if (d > 2047) fail("a depth value wider than the Kinect's 11 bits");
  }
  const RawDepthImage again = must_decode([&] { return decode_fakenect_depth(encode_fakenect_depth(*raw), kSource); }, "PGM");
  if (!(again == *raw)) fail("PGM round trip changed the image");
}

void check_rgb(std::span<const std::uint8_t> bytes) {
  const auto color = decoded_or_error("rgb", [&] { return decode_fakenect_rgb(bytes, kSource); });
  check_kept(bytes, color, kept_color, [](auto b, const std::string& s, ColorImage& out) { decode_fakenect_rgb(b, s, out); });
  if (!color) return;
  const ColorImage again = must_decode([&] { return decode_fakenect_rgb(encode_fakenect_rgb(*color), kSource); }, "PPM");
  if (!(again == *color)) fail("PPM round trip changed the image");
}

}  // namespace
}  // namespace zipfusion::fuzz

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
  const std::span<const std::uint8_t> bytes(data, size);
  zipfusion::fuzz::check_index(std::string(reinterpret_cast<const char*>(data), size));
  zipfusion::fuzz::check_depth(bytes);
  zipfusion::fuzz::check_rgb(bytes);
  return 0;
}
