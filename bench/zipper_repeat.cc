// Zippering of one samba-4cam frame set (or one of the capture given), repeated, for instruction
// counts under callgrind, which are exact where this machine's times vary by a third
// (docs/profile.md):
//   valgrind --tool=callgrind --toggle-collect="$(build/zf_zipper_repeat --callgrind-function)" build/zf_zipper_repeat
// with [--frame F] [--unfiltered] [--repeat N] [--coarse-levels L] [--capture DIR]; the total over N calls divided by
// N is the count per frame set once the first call's allocations are amortised. The function is
// named in full: a pattern such as 'zipfusion::zipper_meshes*' also matches the lambdas inside it
// that are not inlined, and callgrind toggles collection off again on entering each of those (the
// counts before 2026-12-02's sixth session missed the ownership scores and the colours that way).
// --capture takes another capture than samba-4cam (its true poses where it has them), such as a
// synthetic ring from `zipfusion synth --cameras 8`, to see how the zipper's parts grow with the
// cameras.
// Without valgrind it prints the median stage times over the repetitions, one thread unless
// --threads. Either way it prints what the zipper produced, so that a change meant to be only
// faster can be checked to give the same mesh.

#include <algorithm>
#include <bit>
#include <cstdint>
#include <cstdio>
#include <cstdlib>
#include <exception>
#include <string>
#include <utility>
#include <vector>

#include "samba_frame.h"
#include "zipfusion/core/memory.h"
#include "zipfusion/fusion/zipper.h"
#include "zipfusion/pipeline/reconstruct.h"

using namespace zipfusion;

// zipper_meshes as callgrind names it (libstdc++'s demangling), for --toggle-collect. It must follow
// the signature in zipper.h: a name that matches nothing makes callgrind collect nothing, without
// an error ("Collected : 0").
constexpr const char* kZipperFunction =
    "zipfusion::zipper_meshes(std::vector<zipfusion::ZipperCamera, std::allocator<zipfusion::ZipperCamera> > const&, "
    "zipfusion::ZipperOptions const&, zipfusion::ZipperScratch&, zipfusion::TriangleMesh)";

int main(int argc, char** argv) {
  keep_freed_memory();
  int frame = 0, repeat = 3, threads = 1, coarse_levels = ZipperOptions{}.coarse_levels;
  bool filtered = true;
  std::string capture;
  for (int i = 1; i < argc; ++i) {
    const std::string arg = argv[i];
    if (arg == "--callgrind-function") {
      std::printf("%s\n", kZipperFunction);
      return 0;
    }
    if (arg == "--unfiltered") {
      filtered = false;
    } else if (i + 1 < argc && arg == "--capture") {
      capture = argv[++i];
    } else if (i + 1 < argc && (arg == "--frame" || arg == "--repeat" || arg == "--threads" || arg == "--coarse-levels")) {
      const int value = std::atoi(argv[++i]);
      (arg == "--frame" ? frame : arg == "--repeat" ? repeat : arg == "--threads" ? threads : coarse_levels) = value;
    } else {
      std::fprintf(stderr, "usage: zf_zipper_repeat [--frame F] [--unfiltered] [--repeat N] [--threads T] [--coarse-levels L] [--capture DIR] | --callgrind-function\n");
      return 2;
    }
  }
  if (frame < 0 || repeat < 1 || threads < 0 || coarse_levels < 0 || coarse_levels > 4) {
    std::fprintf(stderr, "zf_zipper_repeat: --frame must be >= 0, --repeat >= 1, --threads >= 0 (0 = all cores), --coarse-levels in [0, 4]\n");
    return 2;
  }
  SambaFrame samba;
  try {
    samba = capture.empty() ? load_samba_frame(frame) : load_samba_frame(frame, capture);
  } catch (const std::exception& e) {
    std::fprintf(stderr, "zf_zipper_repeat: %s\n", e.what());
    return 3;
  }
  const std::vector<DepthMesh>& meshes = filtered ? samba.filtered_meshes : samba.meshes;
  const int n = static_cast<int>(meshes.size());
  // The reconstruction's default ownership and seam smoothing for each input.
  const ReconstructOptions defaults{.bilateral = filtered};
  const ZipperOptions options{.coarse_levels = coarse_levels, .ownership = defaults.ownership(), .seam_smoothing_px = defaults.seam_smoothing_px(), .num_threads = threads};
  ZipperScratch scratch;
  // Per stage, as ZipperStats names them, the times of every call.
  const std::vector<std::pair<const char*, double ZipperStats::*>> stages{
      {"pyramid", &ZipperStats::pyramid_ms},   {"overlap", &ZipperStats::overlap_ms},   {"redundancy", &ZipperStats::redundancy_ms},
      {"clipping", &ZipperStats::clipping_ms}, {"assembly", &ZipperStats::assemble_ms}, {"colour", &ZipperStats::color_ms}};
  std::vector<std::vector<double>> stage_ms(stages.size());
  ZipperResult result;
  for (int r = 0; r < repeat; ++r) {
    std::vector<DepthMesh> work = meshes;  // zippering clears bits
    std::vector<ZipperCamera> cameras;
    for (int c = 0; c < n; ++c) cameras.push_back({&work[c], &samba.frames.cameras[c].color, &samba.rig.cameras[c], samba.sdc[c].max_depth_jump_m});
    result = zipper_meshes(cameras, options, scratch, std::move(result.mesh));  // as the pipeline reuses its meshes
    for (size_t k = 0; k < stages.size(); ++k) stage_ms[k].push_back(result.stats.*stages[k].second);
  }
  for (auto& times : stage_ms) std::sort(times.begin(), times.end());
  std::printf("%s frame %d, %s, %d pairs: %zu triangles, %d removed as redundant, %d taken into seams, %d seam triangles\n",
              capture.empty() ? "samba-4cam" : capture.c_str(), frame,
              filtered ? "bilateral-filtered, border ownership" : "unfiltered, smoothness ownership", result.stats.pairs,
              result.mesh.triangles.size(), result.stats.redundant_removed, result.stats.seam_taken, result.stats.seam_added);
  // A fingerprint of the mesh's triangles that does not depend on their order (CGAL's face order
  // may change where the triangulation does not): a sum of mixed hashes of each triangle, rotated
  // to start at its lowest vertex so that its orientation counts.
  std::uint64_t fingerprint = 0;
  for (const Eigen::Vector3i& t : result.mesh.triangles) {
    const int first = t[0] < t[1] ? (t[0] < t[2] ? 0 : 2) : (t[1] < t[2] ? 1 : 2);
    std::uint64_t h = 0x9e3779b97f4a7c15ull;
    for (int k = 0; k < 3; ++k) {
      h ^= static_cast<std::uint32_t>(t[(first + k) % 3]);
      h *= 0xff51afd7ed558ccdull;
      h ^= h >> 33;
    }
    fingerprint += h;
  }
  // The cameras' ownership scores, bit for bit: a change meant to compute them faster must not
  // move them.
  std::uint64_t score_fingerprint = 0xcbf29ce484222325ull;
  for (const ZipperScratch::Camera& camera : scratch.cameras) {
    for (const float cell : camera.ownership.cells) score_fingerprint = (score_fingerprint ^ std::bit_cast<std::uint32_t>(cell)) * 0x100000001b3ull;
  }
  std::printf("ownership score fingerprint %016llx\n", static_cast<unsigned long long>(score_fingerprint));
  std::printf("triangle fingerprint %016llx\n", static_cast<unsigned long long>(fingerprint));
  // The vertices' colours, in their order (a function of the triangles: the used pixels in order).
  std::uint64_t colour_fingerprint = 0xcbf29ce484222325ull;
  for (const Rgb8& c : result.mesh.colors) {
    for (const unsigned char channel : {c.r, c.g, c.b}) colour_fingerprint = (colour_fingerprint ^ channel) * 0x100000001b3ull;
  }
  std::printf("colour fingerprint %016llx\n", static_cast<unsigned long long>(colour_fingerprint));
  // The vertices' positions, bit for bit, in their order: where the seams put their points.
  std::uint64_t position_fingerprint = 0xcbf29ce484222325ull;
  for (const Eigen::Vector3f& p : result.mesh.positions) {
    for (int k = 0; k < 3; ++k) position_fingerprint = (position_fingerprint ^ std::bit_cast<std::uint32_t>(p[k])) * 0x100000001b3ull;
  }
  std::printf("position fingerprint %016llx\n", static_cast<unsigned long long>(position_fingerprint));
  std::printf("median of %d on %d thread(s):", repeat, threads);
  for (size_t k = 0; k < stages.size(); ++k) std::printf("%s %s %.2f ms", k ? "," : "", stages[k].first, stage_ms[k][repeat / 2]);
  std::printf("\n");
  return 0;
}
