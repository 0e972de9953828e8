#include "zipfusion/live/fakenect_dump.h"

#include <algorithm>
#include <cctype>
#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <fstream>
#include <system_error>

#include "zipfusion/core/error.h"
#include "zipfusion/io/file_util.h"
#include "zipfusion/live/kinect_disparity.h"

namespace zipfusion {
namespace {

// The latest recording time an INDEX.txt may name: seconds since 1970, up to the year 2286.
constexpr double kLatestFakenectTimeS = 1e10;

namespace fs = std::filesystem;

std::vector<std::uint8_t> with_header(const std::string& header, const void* data, size_t size) {
  std::vector<std::uint8_t> bytes(header.size() + size);
  std::memcpy(bytes.data(), header.data(), header.size());
  if (size > 0) std::memcpy(bytes.data() + header.size(), data, size);
  return bytes;
}

// The payload of a one-line-header file after checking the header's magic and size; throws
// InvalidInput naming `source`.
std::span<const std::uint8_t> payload(std::span<const std::uint8_t> bytes, const char* magic, size_t bytes_per_pixel, int expected_maxval,
                                      const std::string& source) {
  size_t newline = 0;
  const size_t max_header = std::min<size_t>(bytes.size(), 64);
  while (newline < max_header && bytes[newline] != '\n') ++newline;
  if (newline >= max_header) throw InvalidInput(source + ": header: expected one line \"" + magic + " 640 480 MAXVAL\" followed by a newline");
  char header[64];  // not a std::string: "P5 640 480 65535" is past its inline capacity, and a replay decodes a frame at a time
  std::memcpy(header, bytes.data(), newline);
  header[newline] = 0;
  char kind[3] = {0, 0, 0};
  int width = 0, height = 0, maxval = 0;
  char tail = 0;
  if (std::sscanf(header, "%2s %d %d %d %c", kind, &width, &height, &maxval, &tail) != 4 || std::strcmp(kind, magic) != 0) {
    throw InvalidInput(source + ": header: expected \"" + magic + " 640 480 MAXVAL\", got \"" + printable_excerpt(std::string(header, newline)) + "\"");
  }
  if (maxval != expected_maxval) {
    throw InvalidInput(source + ": header: MAXVAL is " + std::to_string(maxval) + ", fakenect writes " + std::to_string(expected_maxval));
  }
  if (width != kFakenectWidth || height != kFakenectHeight) {
    throw InvalidInput(source + ": header: size " + std::to_string(width) + "x" + std::to_string(height) +
                       " (fakenect replays 640x480 only)");
  }
  const size_t need = static_cast<size_t>(kFakenectWidth) * kFakenectHeight * bytes_per_pixel;
  const size_t have = bytes.size() - newline - 1;
  if (have < need) throw InvalidInput(source + ": truncated: " + std::to_string(have) + " of " + std::to_string(need) + " bytes");
  return bytes.subspan(newline + 1, need);
}

}  // namespace

std::string fakenect_file_name(char type, double time_s, std::uint32_t timestamp) {
  char name[96];
  std::snprintf(name, sizeof name, "%c-%f-%u.%s", type, time_s, timestamp, type == 'd' ? "pgm" : type == 'r' ? "ppm" : "dump");
  return name;
}

std::vector<FakenectIndexEntry> parse_fakenect_index(const std::string& text, const std::string& source) {
  std::vector<FakenectIndexEntry> entries;
  size_t start = 0;
  int line_number = 0;
  while (start < text.size()) {
    size_t end = text.find('\n', start);
    if (end == std::string::npos) end = text.size();
    std::string line = text.substr(start, end - start);
    start = end + 1;
    ++line_number;
    if (!line.empty() && line.back() == '\r') line.pop_back();
    if (line.empty()) continue;
    FakenectIndexEntry entry;
    entry.file = line;
    // fakenect parses "%c-%lf-%u-%*s"; the dash after the timestamp is optional (".pgm" follows).
    char* cursor = nullptr;
    // A file name in the dump folder, as fakenect reads it with scanf's %s: a letter for the type
    // (a NUL "type" cut the name short), then printable ASCII without spaces or '/', at most 255
    // bytes (NAME_MAX; a longer line names no file, and would be quoted whole in the stream's end
    // reason).
    const auto name_byte = [](char c) { return c > 0x20 && c < 0x7f && c != '/'; };
    bool ok = line.size() > 2 && line.size() <= 255 && std::isalpha(static_cast<unsigned char>(line[0])) && line[1] == '-' &&
              std::all_of(line.begin(), line.end(), name_byte);
    if (ok) {
      entry.type = line[0];
      entry.time_s = std::strtod(line.c_str() + 2, &cursor);
      // Seconds since 1970 up to the year 2286: strtod also reads "nan", "inf" and 1e300, at which
      // half a frame period no longer moves a time and grouping the frames never ends.
      ok = cursor != line.c_str() + 2 && *cursor == '-' && entry.time_s >= 0 && entry.time_s <= kLatestFakenectTimeS;
    }
    if (ok) {
      const char* digits = cursor + 1;
      const unsigned long long ts = std::strtoull(digits, &cursor, 10);
      ok = std::isdigit(static_cast<unsigned char>(*digits)) && ts <= 0xffffffffULL;
      entry.timestamp = static_cast<std::uint32_t>(ts);
    }
    if (!ok) {
      throw InvalidInput(source + ": line " + std::to_string(line_number) + ": \"" + printable_excerpt(line) +
                         "\" is not a fakenect file name TYPE-SECONDS-TIMESTAMP (a letter, seconds in [0, 1e10], printable, no spaces; e.g. d-1700000000.000000-0.pgm)");
    }
    entries.push_back(std::move(entry));
  }
  return entries;
}

std::vector<FakenectIndexEntry> read_fakenect_index(const fs::path& dir) {
  const fs::path index = dir / "INDEX.txt";
  const std::vector<std::uint8_t> bytes = read_file_bytes(index);
  return parse_fakenect_index(std::string(bytes.begin(), bytes.end()), index.string());
}

std::vector<std::uint8_t> encode_fakenect_depth(const RawDepthImage& raw) {
  // The buffer as libfreenect hands it over: host-order (little-endian on every Kinect host) uint16.
  static_assert(sizeof(std::uint16_t) == 2);
  std::vector<std::uint8_t> le(raw.data.size() * 2);
  for (size_t i = 0; i < raw.data.size(); ++i) {
    le[2 * i] = static_cast<std::uint8_t>(raw.data[i] & 0xff);
    le[2 * i + 1] = static_cast<std::uint8_t>(raw.data[i] >> 8);
  }
  return with_header("P5 " + std::to_string(raw.width) + " " + std::to_string(raw.height) + " 65535\n", le.data(), le.size());
}

std::vector<std::uint8_t> encode_fakenect_rgb(const ColorImage& color) {
  static_assert(sizeof(Rgb8) == 3);
  return with_header("P6 " + std::to_string(color.width) + " " + std::to_string(color.height) + " 255\n", color.data.data(),
                     color.data.size() * 3);
}

RawDepthImage decode_fakenect_depth(std::span<const std::uint8_t> bytes, const std::string& source) {
  RawDepthImage raw;
  decode_fakenect_depth(bytes, source, raw);
  return raw;
}

void decode_fakenect_depth(std::span<const std::uint8_t> bytes, const std::string& source, RawDepthImage& raw) {
  const std::span<const std::uint8_t> data = payload(bytes, "P5", 2, 65535, source);
  raw.resize_for_overwrite(kFakenectWidth, kFakenectHeight);
  std::uint16_t largest = 0;
  for (size_t i = 0; i < raw.data.size(); ++i) {
    raw.data[i] = static_cast<std::uint16_t>(data[2 * i] | (data[2 * i + 1] << 8));
    largest = std::max(largest, raw.data[i]);
  }
  // The Kinect's raw depth is 11-bit (2047: no measurement); more is another file, most likely a
  // 16-bit PGM in the standard big-endian order rather than fakenect's host order.
  if (largest > kKinectRawNoValue) {
    throw InvalidInput(source + ": pixels: value " + std::to_string(largest) + " above 2047 is not 11-bit Kinect depth (a big-endian PGM?)");
  }
}

ColorImage decode_fakenect_rgb(std::span<const std::uint8_t> bytes, const std::string& source) {
  ColorImage color;
  decode_fakenect_rgb(bytes, source, color);
  return color;
}

void decode_fakenect_rgb(std::span<const std::uint8_t> bytes, const std::string& source, ColorImage& color) {
  const std::span<const std::uint8_t> data = payload(bytes, "P6", 3, 255, source);
  color.resize_for_overwrite(kFakenectWidth, kFakenectHeight);
  std::memcpy(color.data.data(), data.data(), data.size());
}

size_t fakenect_playable_entries(const fs::path& dir, const std::vector<FakenectIndexEntry>& entries, std::string& problem) {
  for (size_t i = 0; i < entries.size(); ++i) {
    const FakenectIndexEntry& e = entries[i];
    const fs::path file = dir / e.file;
    std::error_code ec;
    const std::uintmax_t size = fs::file_size(file, ec);
    if (ec) {
      problem = file.string() + ": missing";
      return i;
    }
    if (e.type != 'd' && e.type != 'r') continue;
    std::ifstream in(file, std::ios::binary);
    char head[64] = {0};
    in.read(head, sizeof head);
    const std::streamsize got = in.gcount();
    std::streamsize header = 0;
    while (header < got && head[header] != '\n') ++header;
    const std::uintmax_t need = static_cast<std::uintmax_t>(header + 1) + static_cast<std::uintmax_t>(kFakenectWidth) * kFakenectHeight * (e.type == 'd' ? 2 : 3);
    if (header >= got || size < need) {
      problem = file.string() + ": truncated: " + std::to_string(size) + " of " + std::to_string(need) + " bytes";
      return i;
    }
  }
  return entries.size();
}

void write_fakenect_file(const fs::path& dir, const FakenectIndexEntry& entry, std::span<const std::uint8_t> bytes) {
  write_file_atomic(dir / entry.file, bytes);
}

void write_fakenect_index(const fs::path& dir, const std::vector<FakenectIndexEntry>& entries) {
  std::string text;
  for (const FakenectIndexEntry& e : entries) text += e.file + "\n";
  write_file_atomic(dir / "INDEX.txt", text);
}

}  // namespace zipfusion
