#pragma once
//! \file
//! Mesh compression with Draco (Google's mesh codec, Debian's libdraco): positions quantised on a
//! fixed grid over the capture volume (the same grid every frame, so a static surface does not
//! shimmer), 8-bit colours, connectivity by Edgebreaker. For streaming one mesh per frame
//! (`zipfusion serve`); the browser decodes it with three.js's DRACOLoader.
//!
//! Thread safety: the functions are pure.

#include <cstdint>
#include <optional>
#include <string>
#include <vector>

#include "zipfusion/core/geometry.h"
#include "zipfusion/core/mesh.h"

namespace zipfusion {

struct DracoOptions {
  int position_bits = 11;     // bits per coordinate over the quantisation box (issue 8: 11)
  // 0 (fastest) to 10 (smallest); Draco's encoder speed is 10 − this. 4, not Draco's default 7:
  // on a live stream encoding time is latency and server time (docs/design.md, "Compression").
  int compression_level = 4;
  bool colors = true;         // encode per-vertex colours when the mesh has them

  void validate() const;  // throws InvalidInput naming the field
};

//! The cube positions are quantised in: `origin` and side `range`, metres.
struct QuantizationBox {
  Eigen::Vector3f origin = Eigen::Vector3f::Zero();
  float range = 1;

  //! The grid's spacing at `bits` per coordinate, metres.
  float step(int bits) const { return range / static_cast<float>((1u << bits) - 1); }
  //! Largest distance between a point and its quantised position, metres.
  float max_error(int bits) const;
};

//! The cube over `volume` (its longest side), grown to hold every position of `mesh` (a mesh may
//! reach outside the volume when cropping is off). Without a volume, the mesh's bounding cube.
QuantizationBox quantization_box(const TriangleMesh& mesh, const std::optional<Box3d>& volume);

//! Whether Draco's quantisation over `box` stays within floats: a finite, positive range, and the
//! range and the box's farthest corner from 0 within a quarter of the largest float (8.5e37).
bool draco_can_quantise(const QuantizationBox& box);

//! Encodes `mesh` (a position per vertex, optional colours, triangles); throws InvalidInput for
//! invalid options or a box Draco cannot quantise (draco_can_quantise), and IoError when Draco
//! fails. Triangles with a repeated corner are left out (Draco's Edgebreaker drops them, and
//! refuses a mesh of only those); a mesh without other triangles (nobody in view) is the empty
//! buffer, which Draco has no encoding for. A triangle whose corners quantise to one grid point
//! is kept. Vertices that no triangle uses are not encoded.
std::string encode_draco(const TriangleMesh& mesh, const QuantizationBox& box, const DracoOptions& options = {});

//! Decodes what encode_draco wrote (or any Draco triangle mesh of bitstream 2.2 without metadata,
//! with 32-bit float positions and optional 8-bit colours, of at most 2^23 vertices and faces;
//! the empty buffer is the empty mesh); throws InvalidInput naming `source` for bytes that are not
//! one, checking the header's counts before Draco allocates what they claim.
TriangleMesh decode_draco(const std::string& bytes, const std::string& source = "draco buffer");

}  // namespace zipfusion
