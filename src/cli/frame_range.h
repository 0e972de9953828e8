#pragma once
// --frames A:B for the CLI: frames A (inclusive) to B (exclusive); "A:" to the end, ":B" from 0,
// "N" a single frame, empty all frames.

#include <algorithm>
#include <charconv>
#include <string>

#include "zipfusion/core/error.h"

namespace zipfusion::cli {

struct FrameRange {
  int begin = 0;
  int end = 0;  // exclusive
};

// A capture whose rig.json has no frames: every command that selects frames says so, not that
// --frames (perhaps not given) selects none.
inline constexpr const char* kNoFrames = "rig.json: frame_count: is 0 (the capture has no frames)";

inline FrameRange parse_frame_range(const std::string& text, int frame_count) {
  // Digits only: std::stoi would also take " 1", "+1" and "-0".
  auto number = [&](const std::string& s, int fallback) {
    if (s.empty()) return fallback;
    int value = 0;
    const auto [end, error] = std::from_chars(s.data(), s.data() + s.size(), value);
    if (error == std::errc::result_out_of_range && std::all_of(s.begin(), s.end(), [](char c) { return c >= '0' && c <= '9'; })) {
      throw InvalidInput("--frames: \"" + text + "\" reaches past the last frame of a capture with " + std::to_string(frame_count) + " frames");
    }
    if (error != std::errc() || end != s.data() + s.size() || s[0] == '-') {
      throw InvalidInput("--frames: expected A:B with whole numbers, got \"" + text + "\"");
    }
    return value;
  };
  auto past_the_end = [&] {
    return InvalidInput("--frames: \"" + text + "\" reaches past the last frame of a capture with " + std::to_string(frame_count) + " frames");
  };
  if (frame_count == 0) throw InvalidInput(kNoFrames);
  FrameRange range{0, frame_count};
  const size_t colon = text.find(':');
  if (colon == std::string::npos) {
    // Frame N is N:N+1, past the end whenever N is (N + 1 does not overflow: N < frame_count).
    if (!text.empty()) {
      const int frame = number(text, 0);
      if (frame >= frame_count) throw past_the_end();
      range = {frame, frame + 1};
    }
  } else {
    range = {number(text.substr(0, colon), 0), number(text.substr(colon + 1), frame_count)};
  }
  if (range.end > frame_count) throw past_the_end();
  if (range.begin >= range.end) {
    throw InvalidInput("--frames: \"" + text + "\" selects no frames of a capture with " + std::to_string(frame_count) + " frames");
  }
  return range;
}

}  // namespace zipfusion::cli
