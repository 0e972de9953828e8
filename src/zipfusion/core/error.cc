#include "zipfusion/core/error.h"

#include <cstdio>

namespace zipfusion {

std::string printable_excerpt(std::string_view bytes, size_t most_chars) {
  std::string out;
  for (const char c : bytes) {
    const auto byte = static_cast<unsigned char>(c);
    char piece[5] = {c, 0};
    if (byte < 0x20 || byte >= 0x7f) std::snprintf(piece, sizeof piece, "\\x%02x", byte);
    if (out.size() + std::char_traits<char>::length(piece) > most_chars) return out + "...";
    out += piece;
  }
  return out;
}

}  // namespace zipfusion
