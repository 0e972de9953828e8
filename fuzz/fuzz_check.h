#pragma once
//! \file
//! What every fuzz target checks (STYLE.md: decoders of untrusted bytes never crash). A decoder
//! either returns a value that is valid and round-trips exactly through its writer, or throws
//! InvalidInput / IoError with a message the CLI can print as is: one line of printable text, of
//! bounded length, naming the source. Anything else (a crash, a sanitizer report, another
//! exception, a bad message, a value that does not round-trip) ends the process, which libFuzzer
//! and the corpus replay report as a failure.

#include <cstdio>
#include <cstdlib>
#include <exception>
#include <optional>
#include <string>

#include "zipfusion/core/error.h"

namespace zipfusion::fuzz {

//! The source name every target passes: errors must contain it.
inline constexpr const char* kSource = "fuzz-input";

//! The longest error message accepted: the source, a field and a few quoted excerpts.
inline constexpr size_t kMostMessageChars = 600;

//! The decoder (a target's name for one of its checks, e.g. "depth") that must accept the current
//! input, or empty. The replay sets it from a corpus file named "valid-DECODER_…", so that a
//! decoder which starts refusing good input fails `make test`; libFuzzer never sets it.
inline std::string& decoder_that_must_accept() {
  static std::string name;
  return name;
}

[[noreturn]] inline void fail(const std::string& what) {
  std::fprintf(stderr, "fuzz check failed: %s\n", printable_excerpt(what, 2000).c_str());
  std::abort();
}

//! An error the CLI prints as is: one line of printable text, naming the input.
inline void check_message(const std::string& message) {
  if (message.size() > kMostMessageChars) fail("error message of " + std::to_string(message.size()) + " characters: " + message);
  for (const char c : message) {
    const auto byte = static_cast<unsigned char>(c);
    if (byte < 0x20 || byte == 0x7f) fail("error message with a control character: " + message);
  }
  if (message.find(kSource) == std::string::npos) fail("error that does not name the source: " + message);
}

//! Calls decode() for the decoder named `decoder`; nullopt when it threw a proper error, else its
//! value.
template <class Decode>
auto decoded_or_error(const char* decoder, Decode decode) -> std::optional<decltype(decode())> {
  std::string message;
  try {
    return decode();
  } catch (const InvalidInput& e) {
    message = e.what();
  } catch (const IoError& e) {
    message = e.what();
  }
  check_message(message);
  if (decoder_that_must_accept() == decoder) fail(std::string(decoder) + " refused an input it must accept: " + message);
  return std::nullopt;
}

//! Decoding what the writer wrote must succeed: the writer's output is valid input by definition.
template <class Decode>
auto must_decode(Decode decode, const char* what) -> decltype(decode()) {
  try {
    return decode();
  } catch (const std::exception& e) {
    fail(std::string(what) + ": the writer's own output was refused: " + e.what());
  }
}

}  // namespace zipfusion::fuzz
