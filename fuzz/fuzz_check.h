#pragma once
//! \file
//! What every fuzz target checks (STYLE.md: decoders of untrusted bytes never crash). A decoder
//! either returns a value that round-trips exactly through its encoder, or throws InvalidInput /
//! IoError with one line that names the source. Anything else (a crash, a sanitizer report,
//! another exception, a multi-line or anonymous message, a value that does not round-trip) ends
//! the process, which libFuzzer and the corpus replay report as a failure.

#include <cstdio>
#include <cstdlib>
#include <exception>
#include <optional>
#include <string>

#include "zipfusion/core/error.h"

namespace zipfusion::fuzz {

//! The source name every target passes: errors must contain it.
inline constexpr const char* kSource = "fuzz-input";

[[noreturn]] inline void fail(const std::string& what) {
  std::fprintf(stderr, "fuzz check failed: %s\n", what.c_str());
  std::abort();
}

//! An error the CLI prints as is: one line, naming the input.
inline void check_message(const std::string& message) {
  if (message.find('\n') != std::string::npos) fail("error of more than one line: " + message);
  if (message.find(kSource) == std::string::npos) fail("error that does not name the source: " + message);
}

//! Calls decode(); nullopt when it threw a proper error, else its value.
template <class Decode>
auto decoded_or_error(Decode decode) -> std::optional<decltype(decode())> {
  try {
    return decode();
  } catch (const InvalidInput& e) {
    check_message(e.what());
  } catch (const IoError& e) {
    check_message(e.what());
  }
  return std::nullopt;
}

//! Decoding what the encoder wrote must succeed: the encoder's output is valid input by definition.
template <class Decode>
auto must_decode(Decode decode, const char* what) -> decltype(decode()) {
  try {
    return decode();
  } catch (const std::exception& e) {
    fail(std::string(what) + ": the encoder's own output was refused: " + e.what());
  }
}

}  // namespace zipfusion::fuzz
