#pragma once
//! \file
//! Whole-file reads and atomic writes (temporary file in the same folder, then rename), so a
//! crash or an error never leaves a half-written file under the final name.

#include <cstdint>
#include <filesystem>
#include <span>
#include <string_view>
#include <vector>

namespace zipfusion {

//! Throws IoError naming the file when it cannot be opened or read.
std::vector<std::uint8_t> read_file_bytes(const std::filesystem::path& path);

//! Writes bytes to path atomically. Throws IoError naming the file on failure.
void write_file_atomic(const std::filesystem::path& path, std::span<const std::uint8_t> bytes);
void write_file_atomic(const std::filesystem::path& path, std::string_view text);

}  // namespace zipfusion
