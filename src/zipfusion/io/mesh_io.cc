#include "zipfusion/io/mesh_io.h"

#include <algorithm>
#include <bit>
#include <cassert>
#include <cctype>
#include <charconv>
#include <cmath>
#include <cstring>
#include <limits>
#include <optional>
#include <utility>

#include "zipfusion/core/error.h"
#include "zipfusion/io/file_util.h"

namespace zipfusion {
namespace {

[[noreturn]] void fail(const std::string& source, const std::string& problem) {
  throw InvalidInput(source + ": " + problem);
}

// A token from the file, quoted for an error message.
std::string quote_token(std::string_view token) {
  std::string quoted = "'";  // built by appending: GCC 12 warns falsely (-Wrestrict) on "'" + string
  quoted += printable_excerpt(token, 40);
  return quoted += "'";
}

std::string number_text(double value) {
  char buf[64];
  const auto result = std::to_chars(buf, buf + sizeof(buf), value);
  return std::string(buf, result.ptr);
}

std::vector<std::string_view> split_whitespace(std::string_view line) {
  std::vector<std::string_view> tokens;
  size_t i = 0;
  while (i < line.size()) {
    while (i < line.size() && std::isspace(static_cast<unsigned char>(line[i]))) ++i;
    const size_t start = i;
    while (i < line.size() && !std::isspace(static_cast<unsigned char>(line[i]))) ++i;
    if (i > start) tokens.push_back(line.substr(start, i - start));
  }
  return tokens;
}

// Splits text into lines on '\n', dropping a trailing '\r'. Keeps the position after each line.
class LineReader {
 public:
  explicit LineReader(std::string_view text) : text_(text) {}
  bool next(std::string_view& line) {
    if (pos_ >= text_.size()) return false;
    const size_t eol = text_.find('\n', pos_);
    const size_t stop = eol == std::string_view::npos ? text_.size() : eol;
    line = text_.substr(pos_, stop - pos_);
    pos_ = eol == std::string_view::npos ? text_.size() : eol + 1;
    if (!line.empty() && line.back() == '\r') line.remove_suffix(1);
    ++line_number_;
    return true;
  }
  size_t position() const { return pos_; }
  int line_number() const { return line_number_; }

 private:
  std::string_view text_;
  size_t pos_ = 0;
  int line_number_ = 0;
};

// from_chars over a whole token; a leading '+' is allowed. False when the token is not a number.
template <typename T>
bool parse_number(std::string_view token, T& value) {
  if (token.size() > 1 && token[0] == '+' && token[1] != '-' && token[1] != '+') token.remove_prefix(1);
  const char* end = token.data() + token.size();
  const auto result = std::from_chars(token.data(), end, value);
  return result.ec == std::errc() && result.ptr == end;
}

std::string to_lower(std::string text) {
  std::transform(text.begin(), text.end(), text.begin(),
                 [](unsigned char c) { return static_cast<char>(std::tolower(c)); });
  return text;
}

// ---- PLY header -------------------------------------------------------------------------------

enum class PlyFormat { kAscii, kBinaryLittleEndian, kBinaryBigEndian };

enum class ScalarType { kInt8, kUInt8, kInt16, kUInt16, kInt32, kUInt32, kFloat32, kFloat64 };

size_t type_size(ScalarType type) {
  switch (type) {
    case ScalarType::kInt8:
    case ScalarType::kUInt8:
      return 1;
    case ScalarType::kInt16:
    case ScalarType::kUInt16:
      return 2;
    case ScalarType::kInt32:
    case ScalarType::kUInt32:
    case ScalarType::kFloat32:
      return 4;
    case ScalarType::kFloat64:
      return 8;
  }
  return 1;
}

bool is_integer(ScalarType type) { return type != ScalarType::kFloat32 && type != ScalarType::kFloat64; }

std::optional<ScalarType> parse_scalar_type(std::string_view name) {
  static constexpr std::pair<std::string_view, ScalarType> kNames[] = {
      {"char", ScalarType::kInt8},      {"int8", ScalarType::kInt8},       {"uchar", ScalarType::kUInt8},
      {"uint8", ScalarType::kUInt8},    {"short", ScalarType::kInt16},     {"int16", ScalarType::kInt16},
      {"ushort", ScalarType::kUInt16},  {"uint16", ScalarType::kUInt16},   {"int", ScalarType::kInt32},
      {"int32", ScalarType::kInt32},    {"uint", ScalarType::kUInt32},     {"uint32", ScalarType::kUInt32},
      {"float", ScalarType::kFloat32},  {"float32", ScalarType::kFloat32}, {"double", ScalarType::kFloat64},
      {"float64", ScalarType::kFloat64}};
  for (const auto& [n, t] : kNames) {
    if (n == name) return t;
  }
  return std::nullopt;
}

struct PlyProperty {
  std::string name;
  ScalarType type = ScalarType::kFloat32;  // the item type for lists
  bool is_list = false;
  ScalarType count_type = ScalarType::kUInt8;  // lists only
};

struct PlyElement {
  std::string name;
  std::uint64_t count = 0;
  std::vector<PlyProperty> properties;

  int find(std::string_view property_name) const {
    for (size_t i = 0; i < properties.size(); ++i) {
      if (properties[i].name == property_name) return static_cast<int>(i);
    }
    return -1;
  }
};

struct PlyHeader {
  PlyFormat format = PlyFormat::kAscii;
  std::vector<PlyElement> elements;
  size_t data_offset = 0;  // first byte after the end_header line
};

PlyHeader parse_ply_header(const std::vector<std::uint8_t>& bytes, const std::string& source) {
  const std::string_view text(reinterpret_cast<const char*>(bytes.data()), bytes.size());
  LineReader lines(text);
  std::string_view line;
  if (!lines.next(line) || line != "ply") fail(source, "not a PLY file (the first line is not 'ply')");

  PlyHeader header;
  bool has_format = false;
  while (lines.next(line)) {
    const std::string where = "header line " + std::to_string(lines.line_number());
    const std::vector<std::string_view> tokens = split_whitespace(line);
    if (tokens.empty()) continue;
    const std::string_view keyword = tokens[0];
    if (keyword == "comment" || keyword == "obj_info") continue;
    if (keyword == "end_header") {
      if (!has_format) fail(source, "header: missing format line");
      header.data_offset = lines.position();
      return header;
    }
    if (keyword == "format") {
      if (tokens.size() != 3) fail(source, where + ": expected 'format TYPE VERSION'");
      if (tokens[1] == "ascii") {
        header.format = PlyFormat::kAscii;
      } else if (tokens[1] == "binary_little_endian") {
        header.format = PlyFormat::kBinaryLittleEndian;
      } else if (tokens[1] == "binary_big_endian") {
        header.format = PlyFormat::kBinaryBigEndian;
      } else {
        fail(source, where + ": unknown format " + quote_token(tokens[1]));
      }
      has_format = true;
    } else if (keyword == "element") {
      if (tokens.size() != 3) fail(source, where + ": expected 'element NAME COUNT'");
      PlyElement element;
      element.name = std::string(tokens[1]);
      if (!parse_number(tokens[2], element.count)) {
        fail(source, where + ": element " + quote_token(element.name) + ": bad count " + quote_token(tokens[2]));
      }
      for (const PlyElement& other : header.elements) {
        if (other.name == element.name) fail(source, where + ": duplicate element " + quote_token(element.name));
      }
      header.elements.push_back(std::move(element));
    } else if (keyword == "property") {
      if (header.elements.empty()) fail(source, where + ": property before any element");
      PlyElement& element = header.elements.back();
      PlyProperty property;
      std::string_view type_name, count_name;
      if (tokens.size() == 5 && tokens[1] == "list") {
        property.is_list = true;
        count_name = tokens[2];
        type_name = tokens[3];
        property.name = std::string(tokens[4]);
      } else if (tokens.size() == 3 && tokens[1] != "list") {
        type_name = tokens[1];
        property.name = std::string(tokens[2]);
      } else {
        fail(source, where + ": expected 'property TYPE NAME' or 'property list COUNT_TYPE TYPE NAME'");
      }
      const std::string what = where + ": property " + quote_token(property.name);
      const std::optional<ScalarType> type = parse_scalar_type(type_name);
      if (!type) fail(source, what + ": unknown type " + quote_token(type_name));
      property.type = *type;
      if (property.is_list) {
        const std::optional<ScalarType> count_type = parse_scalar_type(count_name);
        if (!count_type) fail(source, what + ": unknown list count type " + quote_token(count_name));
        if (!is_integer(*count_type)) fail(source, what + ": list count type must be an integer type");
        property.count_type = *count_type;
      }
      if (element.find(property.name) >= 0) {
        fail(source, what + ": duplicate property in element " + quote_token(element.name));
      }
      element.properties.push_back(std::move(property));
    } else {
      fail(source, where + ": unexpected keyword " + quote_token(keyword));
    }
  }
  fail(source, "truncated header: no end_header line");
}

// ---- PLY body readers -------------------------------------------------------------------------

// Thrown by the readers, turned into InvalidInput with the element named by for_each_element.
struct Truncated {};
struct BadToken {
  std::string_view token;
};

class BinaryReader {
 public:
  BinaryReader(const std::uint8_t* begin, const std::uint8_t* end, bool big_endian)
      : p_(begin), end_(end), swap_(big_endian != (std::endian::native == std::endian::big)) {}

  static constexpr bool kBinary = true;

  size_t remaining() const { return static_cast<size_t>(end_ - p_); }

  double read(ScalarType type) {
    const size_t n = type_size(type);
    if (remaining() < n) throw Truncated{};
    unsigned char b[8];
    std::memcpy(b, p_, n);
    p_ += n;
    if (swap_) std::reverse(b, b + n);
    switch (type) {
      case ScalarType::kInt8:
        return load<std::int8_t>(b);
      case ScalarType::kUInt8:
        return load<std::uint8_t>(b);
      case ScalarType::kInt16:
        return load<std::int16_t>(b);
      case ScalarType::kUInt16:
        return load<std::uint16_t>(b);
      case ScalarType::kInt32:
        return load<std::int32_t>(b);
      case ScalarType::kUInt32:
        return load<std::uint32_t>(b);
      case ScalarType::kFloat32:
        return load<float>(b);
      case ScalarType::kFloat64:
        return load<double>(b);
    }
    return 0;
  }

  void skip(ScalarType type, std::uint64_t count) {
    const size_t n = type_size(type);
    if (count > remaining() / n) throw Truncated{};
    p_ += count * n;
  }

 private:
  template <typename T>
  static double load(const unsigned char* b) {
    T v;
    std::memcpy(&v, b, sizeof(T));
    return static_cast<double>(v);
  }

  const std::uint8_t* p_;
  const std::uint8_t* end_;
  bool swap_;
};

class AsciiReader {
 public:
  AsciiReader(const std::uint8_t* begin, const std::uint8_t* end)
      : text_(reinterpret_cast<const char*>(begin), static_cast<size_t>(end - begin)) {}

  static constexpr bool kBinary = false;

  size_t remaining() const { return text_.size() - pos_; }

  double read(ScalarType /*type*/) {
    const std::string_view token = next_token();
    double value = 0;
    if (!parse_number(token, value)) throw BadToken{token};
    return value;
  }

  void skip(ScalarType /*type*/, std::uint64_t count) {
    for (std::uint64_t i = 0; i < count; ++i) next_token();
  }

 private:
  std::string_view next_token() {
    while (pos_ < text_.size() && std::isspace(static_cast<unsigned char>(text_[pos_]))) ++pos_;
    const size_t start = pos_;
    while (pos_ < text_.size() && !std::isspace(static_cast<unsigned char>(text_[pos_]))) ++pos_;
    if (pos_ == start) throw Truncated{};
    return text_.substr(start, pos_ - start);
  }

  std::string_view text_;
  size_t pos_ = 0;
};

// Runs body(i) for each instance of the element, naming the element in truncation errors.
template <typename Body>
void for_each_element(const PlyElement& element, const std::string& source, Body&& body) {
  std::uint64_t i = 0;
  try {
    for (; i < element.count; ++i) body(i);
  } catch (const Truncated&) {
    fail(source, "truncated data: element " + quote_token(element.name) + " " + std::to_string(i) + " of " +
                     std::to_string(element.count) + " is incomplete");
  } catch (const BadToken& bad) {
    fail(source,
         "element " + quote_token(element.name) + " " + std::to_string(i) + ": bad number " + quote_token(bad.token));
  }
}

// Reads a list count: a non-negative integer. Errors name the element and its number i.
template <typename Reader>
std::uint64_t read_list_count(Reader& reader, const PlyProperty& property, const std::string& source,
                              const std::string& element_name, std::uint64_t i) {
  const double count = reader.read(property.count_type);
  if (!(count >= 0) || count != std::floor(count) || count > 4294967295.0) {
    fail(source, quote_token(element_name) + " " + std::to_string(i) + ": property " + quote_token(property.name) +
                     ": bad list count " + number_text(count));
  }
  return static_cast<std::uint64_t>(count);
}

template <typename Reader>
void skip_property(Reader& reader, const PlyProperty& property, const std::string& source,
                   const std::string& element_name, std::uint64_t i) {
  if (property.is_list) {
    const std::uint64_t n = read_list_count(reader, property, source, element_name, i);
    reader.skip(property.type, n);
  } else {
    reader.skip(property.type, 1);
  }
}

template <typename Reader>
void skip_element(Reader& reader, const PlyElement& element, const std::string& source) {
  if (element.properties.empty()) return;
  const bool fixed_size = std::none_of(element.properties.begin(), element.properties.end(),
                                       [](const PlyProperty& p) { return p.is_list; });
  if (Reader::kBinary && fixed_size) {
    size_t size = 0;
    for (const PlyProperty& p : element.properties) size += type_size(p.type);
    if (element.count > reader.remaining() / size) {
      fail(source, "truncated data: element " + quote_token(element.name) + " needs more bytes than remain");
    }
    reader.skip(ScalarType::kUInt8, element.count * size);
    return;
  }
  for_each_element(element, source, [&](std::uint64_t i) {
    for (const PlyProperty& p : element.properties) skip_property(reader, p, source, element.name, i);
  });
}

// The face's list of corner indices: vertex_indices, else vertex_index; -1 when neither.
int face_index_property(const PlyElement& face) {
  const int j = face.find("vertex_indices");
  return j >= 0 ? j : face.find("vertex_index");
}

// Roles of vertex properties.
constexpr int kSkip = -1;  // 0..2: x y z; 3..5: red green blue

template <typename Reader>
void read_vertices(Reader& reader, const PlyElement& element, const std::string& source, TriangleMesh& mesh) {
  std::vector<int> role(element.properties.size(), kSkip);
  for (int axis = 0; axis < 3; ++axis) {
    const char* name = axis == 0 ? "x" : axis == 1 ? "y" : "z";
    const int j = element.find(name);
    if (j < 0) fail(source, "element 'vertex': missing property '" + std::string(name) + "'");
    if (element.properties[j].is_list)
      fail(source, "element 'vertex': property '" + std::string(name) + "' is a list");
    role[j] = axis;
  }
  static constexpr std::string_view kColorNames[][3] = {
      {"red", "green", "blue"}, {"r", "g", "b"}, {"diffuse_red", "diffuse_green", "diffuse_blue"}};
  bool has_colors = false;
  bool float_colors[3] = {false, false, false};
  for (const auto& names : kColorNames) {
    int js[3];
    bool ok = true;
    for (int c = 0; c < 3; ++c) {
      js[c] = element.find(names[c]);
      ok = ok && js[c] >= 0 && !element.properties[js[c]].is_list;
    }
    if (!ok) continue;
    for (int c = 0; c < 3; ++c) {
      role[js[c]] = 3 + c;
      float_colors[c] = !is_integer(element.properties[js[c]].type);
    }
    has_colors = true;
    break;
  }

  const size_t n = static_cast<size_t>(element.count);
  mesh.positions.resize(n);
  if (has_colors) mesh.colors.resize(n);
  for_each_element(element, source, [&](std::uint64_t i) {
    double values[6] = {0, 0, 0, 0, 0, 0};
    for (size_t j = 0; j < element.properties.size(); ++j) {
      const PlyProperty& property = element.properties[j];
      if (role[j] == kSkip) {
        skip_property(reader, property, source, "vertex", i);
      } else {
        values[role[j]] = reader.read(property.type);
      }
    }
    for (int axis = 0; axis < 3; ++axis) {
      if (!(std::abs(values[axis]) <= std::numeric_limits<float>::max())) {
        fail(source, "vertex " + std::to_string(i) + ": non-finite coordinate " + number_text(values[axis]));
      }
      mesh.positions[i][axis] = static_cast<float>(values[axis]);
    }
    if (has_colors) {
      unsigned char rgb[3];
      for (int c = 0; c < 3; ++c) {
        double v = values[3 + c];
        if (float_colors[c]) v = std::round(v * 255.0);
        rgb[c] = static_cast<unsigned char>(v >= 0 ? std::min(v, 255.0) : 0.0);  // NaN -> 0
      }
      mesh.colors[i] = Rgb8{rgb[0], rgb[1], rgb[2]};
    }
  });
}

template <typename Reader>
void read_faces(Reader& reader, const PlyElement& element, std::uint64_t vertex_count,
                const std::string& source, TriangleMesh& mesh) {
  const int index_property = face_index_property(element);
  if (index_property < 0) fail(source, "element 'face': missing property 'vertex_indices'");
  const PlyProperty& indices = element.properties[index_property];
  if (!indices.is_list) fail(source, "element 'face': property " + quote_token(indices.name) + " must be a list");
  if (!is_integer(indices.type)) {
    fail(source, "element 'face': property " + quote_token(indices.name) + " must have an integer index type");
  }

  // A valid face takes at least a count and 3 indices ("3 0 1 2" in ascii): reserve no more
  // triangles than the remaining bytes could hold.
  const size_t min_face_size =
      Reader::kBinary ? type_size(indices.count_type) + 3 * type_size(indices.type) : 7;
  mesh.triangles.reserve(mesh.triangles.size() + static_cast<size_t>(std::min<std::uint64_t>(
                                                     element.count, reader.remaining() / min_face_size)));
  std::vector<int> corners;
  for_each_element(element, source, [&](std::uint64_t i) {
    const auto where = [i] { return "face " + std::to_string(i); };
    for (size_t j = 0; j < element.properties.size(); ++j) {
      const PlyProperty& property = element.properties[j];
      if (static_cast<int>(j) != index_property) {
        skip_property(reader, property, source, "face", i);
        continue;
      }
      const std::uint64_t n = read_list_count(reader, property, source, "face", i);
      if (n < 3) fail(source, where() + ": fewer than 3 vertices (" + std::to_string(n) + ")");
      if (n > reader.remaining()) throw Truncated{};  // every index takes at least one byte
      corners.clear();
      for (std::uint64_t k = 0; k < n; ++k) {
        const double v = reader.read(property.type);
        if (!(v >= 0) || v != std::floor(v) || v >= static_cast<double>(vertex_count)) {
          fail(source, where() + ": vertex index " + number_text(v) + " out of range (" +
                           std::to_string(vertex_count) + " vertices)");
        }
        corners.push_back(static_cast<int>(v));
      }
      for (size_t k = 1; k + 1 < corners.size(); ++k) {
        mesh.triangles.emplace_back(corners[0], corners[k], corners[k + 1]);
      }
    }
  });
}

template <typename Reader>
TriangleMesh read_ply_body(Reader& reader, const PlyHeader& header, const std::string& source) {
  // Reject counts the remaining bytes cannot hold before allocating anything: every property of
  // every element takes at least one byte (binary: its size; a list at least its count).
  std::uint64_t needed = 0;
  const std::uint64_t available = reader.remaining();
  for (const PlyElement& element : header.elements) {
    std::uint64_t min_size = 0;
    for (const PlyProperty& p : element.properties) {
      min_size += Reader::kBinary ? type_size(p.is_list ? p.count_type : p.type) : 1;
    }
    if (min_size == 0) continue;
    if (element.count > (available - needed) / min_size) {
      fail(source, "truncated data: element " + quote_token(element.name) + " declares " +
                       std::to_string(element.count) + " entries but only " + std::to_string(available) +
                       " bytes of data follow the header");
    }
    needed += element.count * min_size;
  }

  std::uint64_t vertex_count = 0;
  for (const PlyElement& element : header.elements) {
    if (element.name == "vertex") {
      if (element.count > static_cast<std::uint64_t>(std::numeric_limits<int>::max())) {
        fail(source, "element 'vertex': too many vertices (" + std::to_string(element.count) + ")");
      }
      vertex_count = element.count;
    }
  }

  TriangleMesh mesh;
  for (const PlyElement& element : header.elements) {
    if (element.name == "vertex") {
      read_vertices(reader, element, source, mesh);
    } else if (element.name == "face") {
      read_faces(reader, element, vertex_count, source, mesh);
    } else {
      skip_element(reader, element, source);
    }
  }
  return mesh;
}

// ---- PLY writer -------------------------------------------------------------------------------

inline std::uint8_t* put_u32_le(std::uint8_t* out, std::uint32_t bits) {
  out[0] = static_cast<std::uint8_t>(bits);
  out[1] = static_cast<std::uint8_t>(bits >> 8);
  out[2] = static_cast<std::uint8_t>(bits >> 16);
  out[3] = static_cast<std::uint8_t>(bits >> 24);
  return out + 4;
}

// ---- OBJ --------------------------------------------------------------------------------------

void append_float(std::string& out, float value, int precision) {
  char buf[48];
  const auto result = std::to_chars(buf, buf + sizeof(buf), value, std::chars_format::general, precision);
  out.append(buf, result.ptr);
}

void append_int(std::string& out, long long value) {
  char buf[24];
  const auto result = std::to_chars(buf, buf + sizeof(buf), value);
  out.append(buf, result.ptr);
}


}  // namespace

// ---- public -----------------------------------------------------------------------------------

TriangleMesh parse_ply(const std::vector<std::uint8_t>& bytes, const std::string& source) {
  const PlyHeader header = parse_ply_header(bytes, source);
  const std::uint8_t* begin = bytes.data() + header.data_offset;
  const std::uint8_t* end = bytes.data() + bytes.size();
  if (header.format == PlyFormat::kAscii) {
    AsciiReader reader(begin, end);
    return read_ply_body(reader, header, source);
  }
  BinaryReader reader(begin, end, header.format == PlyFormat::kBinaryBigEndian);
  return read_ply_body(reader, header, source);
}

TriangleMesh read_ply(const std::filesystem::path& path) {
  return parse_ply(read_file_bytes(path), path.string());
}

std::vector<std::uint8_t> encode_ply(const TriangleMesh& mesh, const MeshLayout& layout) {
  assert_well_formed(mesh);
  const bool colors = mesh.has_colors() || (layout.colors_when_empty && mesh.positions.empty());
  std::string header = "ply\nformat binary_little_endian 1.0\nelement vertex " +
                       std::to_string(mesh.positions.size()) +
                       "\nproperty float x\nproperty float y\nproperty float z\n";
  if (colors) header += "property uchar red\nproperty uchar green\nproperty uchar blue\n";
  header += "element face " + std::to_string(mesh.triangles.size()) +
            "\nproperty list uchar int vertex_indices\nend_header\n";

  const size_t vertex_size = colors ? 15 : 12;
  std::vector<std::uint8_t> bytes(header.size() + mesh.positions.size() * vertex_size +
                                  mesh.triangles.size() * 13);
  std::memcpy(bytes.data(), header.data(), header.size());
  std::uint8_t* out = bytes.data() + header.size();
  for (size_t i = 0; i < mesh.positions.size(); ++i) {
    for (int axis = 0; axis < 3; ++axis)
      out = put_u32_le(out, std::bit_cast<std::uint32_t>(mesh.positions[i][axis]));
    if (colors) {
      *out++ = mesh.colors[i].r;
      *out++ = mesh.colors[i].g;
      *out++ = mesh.colors[i].b;
    }
  }
  for (const Eigen::Vector3i& t : mesh.triangles) {
    *out++ = 3;
    for (int k = 0; k < 3; ++k) out = put_u32_le(out, static_cast<std::uint32_t>(t[k]));
  }
  assert(out == bytes.data() + bytes.size());
  return bytes;
}

void write_ply(const std::filesystem::path& path, const TriangleMesh& mesh, const MeshLayout& layout) {
  write_file_atomic(path, encode_ply(mesh, layout));
}

namespace {

// The statements of the OBJ format (Wavefront's specification, polygonal and free-form). Any other
// first word means the file is not OBJ (a PLY named .obj, binary bytes): reading it as a mesh
// without faces would pass garbage on as an empty reconstruction.
bool is_obj_statement(std::string_view keyword) {
  static constexpr std::string_view kStatements[] = {"call", "csh",  // "call" is refused where it is read, "csh" ignored (never run)
                                                     "v",     "vt",   "vn",    "vp",    "f",     "l",     "p",        "g",        "o",
                                                     "s",     "mg",   "mtllib", "usemtl", "cstype", "deg",  "bmat",     "step",     "curv",
                                                     "curv2", "surf", "parm",  "trim",  "hole",  "scrv",  "sp",       "end",      "con",
                                                     "bevel", "lod",  "maplib", "usemap", "ctech", "stech", "c_interp", "d_interp", "shadow_obj",
                                                     "trace_obj"};
  return std::find(std::begin(kStatements), std::end(kStatements), keyword) != std::end(kStatements);
}

}  // namespace

TriangleMesh parse_obj(std::string_view text, const std::string& source) {
  if (text.starts_with("\xEF\xBB\xBF")) text.remove_prefix(3);  // a UTF-8 byte order mark (Windows exporters)
  TriangleMesh mesh;
  bool all_colored = true;
  std::vector<int> corners;
  LineReader lines(text);
  std::string_view line;
  while (lines.next(line)) {
    const size_t hash = line.find('#');
    if (hash != std::string_view::npos) line = line.substr(0, hash);
    const std::vector<std::string_view> tokens = split_whitespace(line);
    if (tokens.empty()) continue;
    const std::string where = "line " + std::to_string(lines.line_number());
    if (!is_obj_statement(tokens[0])) fail(source, where + ": not an OBJ statement: " + quote_token(tokens[0]) + " (not an OBJ file?)");
    if (tokens[0] == "call") fail(source, where + ": \"call\" includes another file, which is not read; merge the files into one");
    if (tokens[0] == "v") {
      if (tokens.size() < 4) fail(source, where + ": a vertex needs x y z");
      if (mesh.positions.size() >= static_cast<size_t>(std::numeric_limits<int>::max())) {
        fail(source, where + ": too many vertices");
      }
      float values[6] = {0, 0, 0, 0, 0, 0};
      const bool colored = tokens.size() >= 7;
      for (int k = 0; k < (colored ? 6 : 3); ++k) {
        const std::string_view token = tokens[1 + k];
        if (!parse_number(token, values[k]) || !std::isfinite(values[k])) {
          fail(source, where + ": bad number " + quote_token(token));
        }
      }
      mesh.positions.emplace_back(values[0], values[1], values[2]);
      all_colored = all_colored && colored;
      if (all_colored) {
        unsigned char rgb[3];
        for (int c = 0; c < 3; ++c) {
          const float v = std::round(values[3 + c] * 255.0f);
          rgb[c] = static_cast<unsigned char>(std::clamp(v, 0.0f, 255.0f));
        }
        mesh.colors.push_back(Rgb8{rgb[0], rgb[1], rgb[2]});
      }
    } else if (tokens[0] == "f") {
      if (tokens.size() < 4) fail(source, where + ": a face needs at least 3 vertices");
      const long long vertex_count = static_cast<long long>(mesh.positions.size());
      corners.clear();
      for (size_t k = 1; k < tokens.size(); ++k) {
        const std::string_view token = tokens[k];
        const std::string_view index_text = token.substr(0, token.find('/'));
        long long index = 0;
        if (!parse_number(index_text, index) || index == 0)
          fail(source, where + ": bad face index " + quote_token(token));
        const long long resolved = index > 0 ? index - 1 : vertex_count + index;
        if (resolved < 0 || resolved >= vertex_count) {
          fail(source, where + ": vertex index " + std::to_string(index) + " out of range (" +
                           std::to_string(vertex_count) + " vertices so far)");
        }
        corners.push_back(static_cast<int>(resolved));
      }
      for (size_t k = 1; k + 1 < corners.size(); ++k) {
        mesh.triangles.emplace_back(corners[0], corners[k], corners[k + 1]);
      }
    }
  }
  if (!all_colored) mesh.colors.clear();
  return mesh;
}

TriangleMesh read_obj(const std::filesystem::path& path) {
  const std::vector<std::uint8_t> bytes = read_file_bytes(path);
  return parse_obj(std::string_view(reinterpret_cast<const char*>(bytes.data()), bytes.size()),
                   path.string());
}

std::string encode_obj(const TriangleMesh& mesh) {
  assert_well_formed(mesh);
  const bool colors = mesh.has_colors();
  std::string out;
  out.reserve(mesh.positions.size() * (colors ? 72 : 40) + mesh.triangles.size() * 24);
  for (size_t i = 0; i < mesh.positions.size(); ++i) {
    out += 'v';
    for (int axis = 0; axis < 3; ++axis) {
      out += ' ';
      append_float(out, mesh.positions[i][axis], 9);
    }
    if (colors) {
      const Rgb8 c = mesh.colors[i];
      for (const unsigned char channel : {c.r, c.g, c.b}) {
        out += ' ';
        append_float(out, static_cast<float>(channel) / 255.0f, 6);
      }
    }
    out += '\n';
  }
  for (const Eigen::Vector3i& t : mesh.triangles) {
    out += 'f';
    for (int k = 0; k < 3; ++k) {
      out += ' ';
      append_int(out, static_cast<long long>(t[k]) + 1);
    }
    out += '\n';
  }
  return out;
}

void write_obj(const std::filesystem::path& path, const TriangleMesh& mesh) {
  write_file_atomic(path, encode_obj(mesh));
}

TriangleMesh read_mesh(const std::filesystem::path& path) {
  const std::string extension = to_lower(path.extension().string());
  if (extension == ".ply") return read_ply(path);
  if (extension == ".obj") return read_obj(path);
  fail(path.string(), "unsupported mesh file extension " + quote_token(path.extension().string()) +
                          " (expected .ply or .obj)");
}

void write_mesh(const std::filesystem::path& path, const TriangleMesh& mesh, const MeshLayout& layout) {
  const std::string extension = to_lower(path.extension().string());
  if (extension == ".ply") return write_ply(path, mesh, layout);
  if (extension == ".obj") return write_obj(path, mesh);
  fail(path.string(), "unsupported mesh file extension " + quote_token(path.extension().string()) +
                          " (expected .ply or .obj)");
}

}  // namespace zipfusion
