#pragma once
//! \file
//! Errors for bad external input (files, rig.json, options). The library throws these; only the
//! CLI prints them. Broken internal preconditions are asserts, not exceptions.

#include <stdexcept>
#include <string>

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

}  // namespace zipfusion
