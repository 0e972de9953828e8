#pragma once
//! \file
//! Triangle mesh files: PLY (read: ascii, binary little/big endian; write: binary little endian)
//! and Wavefront OBJ (positions, optional per-vertex colours, faces).
//!
//! Readers take untrusted bytes: every read is bounds-checked and element counts are checked
//! against the bytes that could hold them before anything is allocated. Bad input throws
//! InvalidInput ("FILE: what: problem"); a file that cannot be read or written throws IoError.
//! Polygons with more than three corners are fan-triangulated (0 1 2, 0 2 3, ...).
//! Thread safety: all functions are free of shared state and may run concurrently.

#include <cstdint>
#include <filesystem>
#include <string>
#include <string_view>
#include <vector>

#include "zipfusion/core/mesh.h"

namespace zipfusion {

//! Reads a .ply or .obj file (extension case-insensitive); any other extension is InvalidInput.
TriangleMesh read_mesh(const std::filesystem::path& path);

//! How a mesh file is laid out beyond what the mesh holds.
struct MeshLayout {
  //! A PLY of a mesh without vertices declares the colour properties anyway, so that every frame
  //! of a coloured sequence has the same header (an OBJ without vertices has nothing to colour).
  bool colors_when_empty = false;
};

//! Writes a .ply (write_ply) or .obj (write_obj) file atomically; other extensions: InvalidInput.
//! Precondition (assert): colours empty or one per position, indices in range.
void write_mesh(const std::filesystem::path& path, const TriangleMesh& mesh, const MeshLayout& layout = {});

// --- PLY ---------------------------------------------------------------------------------------

//! Parses PLY bytes; `source` names the file in error messages.
//! - format ascii 1.0, binary_little_endian 1.0 or binary_big_endian 1.0.
//! - Scalar types char/uchar/short/ushort/int/uint/float/double and their aliases
//!   int8/uint8/int16/uint16/int32/uint32/float32/float64.
//! - element vertex: x, y, z required (any scalar type; finite); colour from red/green/blue,
//!   r/g/b or diffuse_red/diffuse_green/diffuse_blue when all three are present (integer types
//!   clamped to 0..255, float types scaled from 0..1). Other properties are skipped.
//! - element face: list property vertex_indices (or vertex_index) with integer count and index
//!   types; faces with fewer than 3 corners or an index outside the vertices are InvalidInput
//!   naming the face number. Other face properties are skipped.
//! - Other elements are skipped, lists included. Bytes after the last element are ignored.
TriangleMesh parse_ply(const std::vector<std::uint8_t>& bytes, const std::string& source);

//! read_file_bytes + parse_ply.
TriangleMesh read_ply(const std::filesystem::path& path);

//! Binary little-endian PLY, the ground-truth format of ../shared/FORMATS.md, exactly:
//! element vertex N; property float x, y, z; (when the mesh has colours) property uchar red,
//! green, blue; element face M; property list uchar int vertex_indices. No comments.
std::vector<std::uint8_t> encode_ply(const TriangleMesh& mesh, const MeshLayout& layout = {});

//! encode_ply written atomically (write_file_atomic).
void write_ply(const std::filesystem::path& path, const TriangleMesh& mesh, const MeshLayout& layout = {});

// --- OBJ ---------------------------------------------------------------------------------------

//! Parses OBJ text; `source` names the file in error messages ("FILE: line N: problem").
//! - `v x y z [w]` or `v x y z r g b` (colours as floats 0..1, scaled to 0..255 and rounded).
//!   Colours are kept only when every vertex has them.
//! - `f` corners `i`, `i/t`, `i/t/n` or `i//n`; 1-based, negative = relative to the vertices
//!   read so far; an index must name a vertex defined on an earlier line.
//! - All other lines (vt, vn, g, o, s, usemtl, mtllib, l, comments) are ignored.
TriangleMesh parse_obj(std::string_view text, const std::string& source);

//! read_file_bytes + parse_obj.
TriangleMesh read_obj(const std::filesystem::path& path);

//! OBJ text: `v x y z` (or `v x y z r g b` with colours in 0..1) with 9 significant digits, so
//! floats round-trip exactly, then `f a b c` with 1-based indices.
std::string encode_obj(const TriangleMesh& mesh);

//! encode_obj written atomically (write_file_atomic).
void write_obj(const std::filesystem::path& path, const TriangleMesh& mesh);

}  // namespace zipfusion
