#pragma once
//! \file
//! Errors for bad external input (files, rig.json, options). The library throws these; only the
//! CLI prints them. Broken internal preconditions are asserts, not exceptions.

#include <algorithm>
#include <cstdio>
#include <stdexcept>
#include <string>
#include <string_view>

namespace zipfusion {

//! Input that is well-formed to the OS but wrong for us: a missing key, a non-rigid matrix, an
//! image of the wrong size. The message names the file and the field.
class InvalidInput : public std::runtime_error {
 public:
  using std::runtime_error::runtime_error;
};

//! A file that cannot be opened, read, decoded or written.
class IoError : public std::runtime_error {
 public:
  using std::runtime_error::runtime_error;
};

//! Bytes of an input as an error message may quote them: at most `most_bytes`, then "...", and
//! every byte that is not printable ASCII as \xNN, so a binary file or a control character never
//! reaches the terminal raw, and the message stays one line.
inline std::string printable_excerpt(std::string_view bytes, size_t most_bytes = 80) {
  std::string out;
  for (size_t i = 0; i < std::min(bytes.size(), most_bytes); ++i) {
    const auto c = static_cast<unsigned char>(bytes[i]);
    if (c >= 0x20 && c < 0x7f) {
      out += static_cast<char>(c);
    } else {
      char escaped[5];
      std::snprintf(escaped, sizeof escaped, "\\x%02x", c);
      out += escaped;
    }
  }
  if (bytes.size() > most_bytes) out += "...";
  return out;
}

}  // namespace zipfusion
