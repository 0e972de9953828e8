#include "zipfusion/depth/color_lookup.h"

#include <algorithm>
#include <cstring>

namespace zipfusion {

void lookup_colors(const DepthMesh& mesh, const CameraModel& camera, const ColorImage* color, std::vector<Rgb8>& out) {
  const int count = mesh.width * mesh.height;
  // kNoColor is grey 128 in every byte, so a memset fills it (a loop over 3-byte pixels was a
  // sixth of this function's time).
  static_assert(sizeof(Rgb8) == 3 && kNoColor.r == 128 && kNoColor.g == 128 && kNoColor.b == 128);
  out.resize(count);
  std::memset(static_cast<void*>(out.data()), 128, out.size() * sizeof(Rgb8));
  const ColorLookup lookup(camera, color);
  if (!lookup.has_image()) return;
  const PixelBox box = mesh.box();
  for (int v = box.v0; v < box.v1; ++v) {
    const float* depth = mesh.depth.data() + static_cast<size_t>(v) * mesh.width;
    Rgb8* colors = out.data() + static_cast<size_t>(v) * mesh.width;
    for (int u = box.u0; u < box.u1; ++u) {
      if (depth[u] > 0) colors[u] = lookup.at(u, v, depth[u]);
    }
  }
}

}  // namespace zipfusion
