#pragma once
//! \file
//! Errors for bad external input (files, rig.json, options). The library throws these; only the
//! CLI prints them. Broken internal preconditions are asserts, not exceptions.

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

//! A file whose bytes cannot be decoded: corrupt, truncated, not the format its name says. Bad
//! data in one file (a recorder killed mid-write, a bad sector), where InvalidInput's other file
//! errors (a wrong size or bit depth) break the capture's contract and hold for every frame.
class CorruptFile : public InvalidInput {
 public:
  using InvalidInput::InvalidInput;
};

//! A file that cannot be opened, read or written (or looked at: a loop of links).
class IoError : public std::runtime_error {
 public:
  using std::runtime_error::runtime_error;
};

//! Bytes of an input as an error message may quote them: every byte that is not printable ASCII
//! as \xNN, so a binary file or a control character never reaches the terminal raw and the
//! message stays one line; cut with "..." to at most `most_chars` characters (plus the dots).
std::string printable_excerpt(std::string_view bytes, size_t most_chars = 80);

}  // namespace zipfusion
