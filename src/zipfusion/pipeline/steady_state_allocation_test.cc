// Steady state allocates nothing per frame set (issue 6): every allocation in this test binary is
// counted by replacing the global operator new, and a FrameReconstructor runs the same samba-4cam
// frame sets twice: the first pass grows its buffers, the second must not allocate (separate
// meshes) or must allocate nothing the size of an image (zipper: CGAL's Delaunay triangulation
// and OpenCV's morphology allocate inside every call; docs/design.md).

#include <gtest/gtest.h>

#include <cstdio>
#include <filesystem>
#include <utility>
#include <vector>

#include "zipfusion/core/allocation_count_test_util.h"
#include "zipfusion/core/parallel.h"
#include "zipfusion/io/capture.h"
#include "zipfusion/pipeline/reconstruct.h"

namespace zipfusion {
namespace {

namespace fs = std::filesystem;

const fs::path kSamba = fs::path(ZF_SOURCE_DIR) / ".." / "shared" / "data" / "samba-4cam";

struct Allocations {
  long long count = 0;
  long long bytes = 0;
  size_t largest = 0;
};

// What reconstructing `frames` once more allocates, after a first pass over the same frame sets.
// Meshes go back to the reconstructor after each frame set, as the pipeline's sink does.
Allocations steady_state_allocations(const std::vector<FrameSet>& frames, const ReconstructOptions& options) {
  FrameReconstructor reconstructor(read_rig(kSamba / "ground_truth" / "rig.json"), options);
  auto pass = [&] {
    for (const FrameSet& frame : frames) {
      FrameResult result = reconstructor.reconstruct(frame);
      EXPECT_GT(result.mesh.triangle_count(), 100000u);
      reconstructor.recycle(std::move(result.mesh));
    }
  };
  pass();
  const long long count = g_allocations.load(), bytes = g_bytes.load();
  g_largest = 0;
  pass();
  return {g_allocations.load() - count, g_bytes.load() - bytes, g_largest.load()};
}

class SteadyState : public testing::Test {
 protected:
  static void SetUpTestSuite() {
    if (!fs::exists(kSamba / "rig.json")) return;
    const Capture capture = Capture::open(kSamba);
    for (int f = 0; f < 3; ++f) frames_.push_back(capture.load_frame(f * 10));
  }
  static void TearDownTestSuite() { frames_.clear(); }
  void SetUp() override {
    if (frames_.empty()) GTEST_SKIP() << "no " << kSamba;
  }
  static std::vector<FrameSet> frames_;
};
std::vector<FrameSet> SteadyState::frames_;

// parallel_for allocates nothing once its pool has started, whatever the body captures and however
// often it is called: a std::function holding the body, or a deque of blocks that takes a node
// every dozen blocks, would (a frame set makes about 40 calls of one block per worker each).
TEST(ParallelFor, AllocatesNothing) {
  std::vector<long long> sums(64, 0);
  long long a = 1, b = 2, c = 3;
  auto run = [&] {
    // Captures five references: more than std::function holds without the heap.
    parallel_for(0, 64, [&](int i) { sums[i] += a + b + c + static_cast<long long>(sums.size()); }, 0);
  };
  run();  // starts the pool
  const long long before = g_allocations.load();
  for (int k = 0; k < 1000; ++k) run();
  EXPECT_EQ(g_allocations.load() - before, 0);
  for (long long s : sums) EXPECT_EQ(s, 1001 * (6 + 64));
}

TEST_F(SteadyState, SeparateMeshesAllocateNothing) {
  for (const auto& [bilateral, separable] : {std::pair{false, false}, std::pair{true, false}, std::pair{true, true}}) {
    ReconstructOptions options{.mode = ReconstructMode::kSeparate, .bilateral = bilateral};
    options.filter.separable = separable;
    const Allocations a = steady_state_allocations(frames_, options);
    EXPECT_EQ(a.count, 0) << "bilateral " << bilateral << " separable " << separable << ": " << a.bytes << " bytes, largest " << a.largest;
  }
}

// The zipper's seams are triangulated by CGAL, whose triangulation allocates when it is made and
// as it grows, and whose insertion of a point outside the hull and removal of a vertex allocate
// lists; OpenCV's dilation and erosion allocate their filter objects. None of that is the size of
// an image: a buffer that is (640×480 floats are 1.2 MB) must be kept in a scratch between
// frames. The count (about 800–850 a frame set; 4 700–6 400 before `constrain` replaced CGAL's
// constraint insertion and the seams' arrays moved into the scratch) is bounded too, so that the
// zipper's own arrays stay in its scratch.
TEST_F(SteadyState, ZipperAllocatesNoImageSizedBuffer) {
  constexpr size_t kLargestAllowed = 256 * 1024;
  constexpr long long kMostPerFrameSet = 1200;
  for (bool bilateral : {false, true}) {
    const Allocations a = steady_state_allocations(frames_, {.mode = ReconstructMode::kZipper, .bilateral = bilateral});
    EXPECT_LT(a.largest, kLargestAllowed) << "bilateral " << bilateral;
    EXPECT_LT(a.count, kMostPerFrameSet * static_cast<long long>(frames_.size())) << "bilateral " << bilateral;
    std::printf("zipper, bilateral %d: %.0f allocations and %.0f bytes a frame set, the largest %zu bytes\n", bilateral,
                static_cast<double>(a.count) / static_cast<double>(frames_.size()), static_cast<double>(a.bytes) / static_cast<double>(frames_.size()),
                a.largest);
  }
}

}  // namespace
}  // namespace zipfusion
