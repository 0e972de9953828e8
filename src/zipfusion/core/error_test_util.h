#pragma once
//! \file
//! The message of the InvalidInput a call throws, for tests of error messages (header only, for
//! tests).

#include <string>
#include <string_view>
#include <utility>

#include "zipfusion/core/error.h"

namespace zipfusion {

//! What invalid_input_message returns when the call throws nothing: no expected message contains
//! it, so a check of the message fails.
inline constexpr std::string_view kNoInvalidInput = "(no InvalidInput thrown)";

//! The message of the InvalidInput (or subclass, such as CorruptFile) that `call` throws, or
//! kNoInvalidInput when it returns normally (any other exception propagates, and GoogleTest
//! reports it).
template <typename Call>
std::string invalid_input_message(Call&& call) {
  try {
    std::forward<Call>(call)();
  } catch (const InvalidInput& e) {
    return e.what();
  }
  return std::string(kNoInvalidInput);
}

}  // namespace zipfusion
