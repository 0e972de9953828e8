#pragma once
//! \file
//! The fakenect dump format (libfreenect 0.5's `fakenect-record` writes it, its fakenect library
//! replays it through the libfreenect API as if a Kinect were plugged in):
//!
//!     DIR/INDEX.txt                      one file name per line, in the order they were captured
//!     DIR/d-<seconds>-<timestamp>.pgm    depth: "P5 640 480 65535\n" + 640·480 little-endian
//!                                        uint16 raw 11-bit values (2047 = none)
//!     DIR/r-<seconds>-<timestamp>.ppm    colour: "P6 640 480 255\n" + 640·480·3 bytes RGB
//!     DIR/a-<seconds>-<timestamp>.dump   accelerometer state (ignored here)
//!
//! <seconds> is the recording host's time (printf %f), by whose differences fakenect paces the
//! replay; <timestamp> is the device timestamp handed to the callback (%u). Each file is a
//! one-line header followed by the raw buffer libfreenect delivered (not a standard 16-bit PGM,
//! which would be big-endian).
//!
//! Readers throw InvalidInput naming the file (and the INDEX.txt line) for malformed content and
//! IoError for files that cannot be read; decoders bounds-check every byte.

#include <cstdint>
#include <filesystem>
#include <span>
#include <string>
#include <vector>

#include "zipfusion/core/image.h"

namespace zipfusion {

inline constexpr int kFakenectWidth = 640;   // FREENECT_RESOLUTION_MEDIUM, the only mode fakenect replays
inline constexpr int kFakenectHeight = 480;

using RawDepthImage = Image<std::uint16_t>;  // 11-bit raw disparity values, 2047 = none

//! One line of INDEX.txt.
struct FakenectIndexEntry {
  char type = 'd';              // 'd' depth, 'r' colour, 'a' accelerometer
  double time_s = 0;            // the recording host's time, seconds
  std::uint32_t timestamp = 0;  // the device timestamp
  std::string file;             // file name inside the dump folder
};

//! "d-1700000000.033333-2000000.pgm" (the name fakenect-record gives; type 'd' → .pgm, 'r' → .ppm).
std::string fakenect_file_name(char type, double time_s, std::uint32_t timestamp);

//! Parses INDEX.txt text (`source` names it in errors). Lines of unknown type are kept (type as
//! written); a name that does not start with "<type>-<seconds>-<timestamp>" is an error naming
//! the line. Empty lines are skipped.
std::vector<FakenectIndexEntry> parse_fakenect_index(const std::string& text, const std::string& source);
std::vector<FakenectIndexEntry> read_fakenect_index(const std::filesystem::path& dir);

std::vector<std::uint8_t> encode_fakenect_depth(const RawDepthImage& raw);
std::vector<std::uint8_t> encode_fakenect_rgb(const ColorImage& color);

//! Decoders: the header must be one line "P5 W H MAXVAL" (depth) or "P6 W H MAXVAL" (colour)
//! with W×H = 640×480, followed by at least the buffer's bytes (fakenect-record may pad).
//! Throws InvalidInput naming `source`: a wrong magic or size, or a truncated buffer ("truncated:
//! N of 614400 bytes").
RawDepthImage decode_fakenect_depth(std::span<const std::uint8_t> bytes, const std::string& source);
ColorImage decode_fakenect_rgb(std::span<const std::uint8_t> bytes, const std::string& source);
//! The same into an image whose buffer is reused (a replay, frame after frame). On a throw the
//! image's size and pixels are unspecified.
void decode_fakenect_depth(std::span<const std::uint8_t> bytes, const std::string& source, RawDepthImage& raw);
void decode_fakenect_rgb(std::span<const std::uint8_t> bytes, const std::string& source, ColorImage& color);

//! How many leading entries fakenect can replay: it stops (exits the process, or reads past its
//! buffer) at the first listed file that is missing, or, for depth and colour, shorter than its
//! header line plus the 640×480 buffer. Returns entries.size() when every file is whole; sets
//! `problem` to "FILE: missing" / "FILE: truncated: N of M bytes" for the first bad one.
size_t fakenect_playable_entries(const std::filesystem::path& dir, const std::vector<FakenectIndexEntry>& entries, std::string& problem);

//! Writes one frame file atomically, and INDEX.txt (atomically) listing `entries` in order.
void write_fakenect_file(const std::filesystem::path& dir, const FakenectIndexEntry& entry, std::span<const std::uint8_t> bytes);
void write_fakenect_index(const std::filesystem::path& dir, const std::vector<FakenectIndexEntry>& entries);

}  // namespace zipfusion
