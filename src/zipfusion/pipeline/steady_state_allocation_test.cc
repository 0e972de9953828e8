// Steady state allocates nothing per frame set (issue 6): every allocation in this test binary is
// counted by replacing the global operator new, and a FrameReconstructor runs the same samba-4cam
// frame sets again after passes that grow its buffers: that pass must not allocate; nor must
// decoding them again into the same frame set, nor the whole pipeline, source to sink, once its
// frame sets, queues and meshes go round (docs/design.md, *The frame pipeline and threads*), from
// a capture or from live cameras.

#include <gtest/gtest.h>

#include <algorithm>
#include <atomic>
#include <chrono>
#include <cstdio>
#include <filesystem>
#include <numeric>
#include <ostream>
#include <thread>
#include <utility>
#include <vector>

#include "zipfusion/core/allocation_count_test_util.h"
#include "zipfusion/core/parallel.h"
#include "zipfusion/io/capture.h"
#include "zipfusion/live/live_rig.h"
#include "zipfusion/live/replay_camera.h"
#include "zipfusion/pipeline/background_registration.h"
#include "zipfusion/pipeline/pipeline.h"
#include "zipfusion/pipeline/reconstruct.h"
#include "zipfusion/synth/fakenect_scene.h"

namespace zipfusion {
namespace {

namespace fs = std::filesystem;

const fs::path kSamba = fs::path(ZF_SOURCE_DIR) / ".." / "shared" / "data" / "samba-4cam";

struct Allocations {
  long long count = 0;
  long long bytes = 0;
  size_t largest = 0;
};

// What each pass over `frames` after the first allocates (`measured` passes): the first grows the
// buffers, and the k-th measured pass comes after k warm-up passes. Meshes go back to the
// reconstructor after each frame set, as the pipeline's sink does.
std::vector<Allocations> steady_state_allocations(const std::vector<FrameSet>& frames, const ReconstructOptions& options, int measured = 1) {
  FrameReconstructor reconstructor(read_rig(kSamba / "ground_truth" / "rig.json"), options);
  auto pass = [&] {
    for (const FrameSet& frame : frames) {
      FrameResult result = reconstructor.reconstruct(frame);
      EXPECT_GT(result.mesh.triangle_count(), 100000u);
      reconstructor.recycle(std::move(result.mesh));
    }
  };
  pass();
  std::vector<Allocations> passes;
  passes.reserve(measured);  // not inside a measured pass
  for (int k = 0; k < measured; ++k) {
    const long long count = g_allocations.load(), bytes = g_bytes.load();
    g_largest = 0;
    pass();
    passes.push_back({g_allocations.load() - count, g_bytes.load() - bytes, g_largest.load()});
  }
  return passes;
}

class SteadyState : public testing::Test {
 protected:
  static constexpr int kFrameIndices[3] = {0, 10, 20};
  static void SetUpTestSuite() {
    if (!fs::exists(kSamba / "rig.json")) return;
    const Capture capture = Capture::open(kSamba);
    for (int f : kFrameIndices) frames_.push_back(capture.load_frame(f));
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
    const Allocations a = steady_state_allocations(frames_, options)[0];
    EXPECT_EQ(a.count, 0) << "bilateral " << bilateral << " separable " << separable << ": " << a.bytes << " bytes, largest " << a.largest;
  }
}

// The zipper keeps its arrays, its seams' CGAL triangulations (clear_keeping_memory) and its
// masks' buffers (binary_image.h) between frame sets, and neither inserts seam points, constrains
// kept edges nor removes crease points through CGAL's allocating calls (insert_points, constrain,
// remove_point) but in rare cases those leave to CGAL, none in these frame sets. Before 2026-12-07
// it allocated 800–850 times a frame set (CGAL's lists and blocks, OpenCV's filter objects), and
// 4 700–6 400 times before 2026-12-06. After one warm-up pass a buffer can still grow once: which
// of a camera's pairs first fills its FRBR worklist depends on the frame set before (one 32 kB
// allocation in three frame sets with the filter, and after a second warm-up pass none).
TEST_F(SteadyState, ZipperAllocatesNothing) {
  for (bool bilateral : {false, true}) {
    const ReconstructOptions options{.mode = ReconstructMode::kZipper, .bilateral = bilateral};
    const std::vector<Allocations> passes = steady_state_allocations(frames_, options, 2);
    const Allocations &once = passes[0], &a = passes[1];
    EXPECT_LE(once.count, 3) << "bilateral " << bilateral << ", after one warm-up pass";
    EXPECT_EQ(a.count, 0) << "bilateral " << bilateral << ": " << a.bytes << " bytes, largest " << a.largest;
    std::printf("zipper, bilateral %d: %lld allocations in %zu frame sets after one warm-up pass, %lld after two\n", bilateral, once.count,
                frames_.size(), a.count);
  }
}

// Decoding frame sets 0, 10 and 20 again into the same FrameSet (as the pipeline does with the sets
// it hands back) allocates nothing: each camera's images are decoded into the buffers already
// there, the file's bytes into its decoder's. Before, each frame set took new images, file buffers
// and paths (a FrameSet of four cameras: 8 images, 6.1 MB). The images are what a fresh load gives.
// libjpeg's own working memory (malloc, not operator new) is outside this count: ImageDecoder.
TEST_F(SteadyState, DecodingAllocatesNothing) {
  const Capture capture = Capture::open(kSamba);
  FrameSetReader reader(capture);
  FrameSet set;
  for (int f : kFrameIndices) reader.read(f, set);
  long long most = 0;
  for (int k = 0; k < 3; ++k) {
    const long long count = g_allocations.load(), bytes = g_bytes.load();
    g_largest = 0;
    reader.read(kFrameIndices[k], set);
    const long long allocated = g_allocations.load() - count;
    EXPECT_EQ(allocated, 0) << "frame " << kFrameIndices[k] << ": " << g_bytes.load() - bytes << " bytes, largest " << g_largest.load();
    most = std::max(most, allocated);
    ASSERT_EQ(set.cameras.size(), frames_[k].cameras.size());
    EXPECT_EQ(set.index, kFrameIndices[k]);
    for (size_t c = 0; c < set.cameras.size(); ++c) {
      const CameraFrame &got = set.cameras[c], &fresh = frames_[k].cameras[c];
      EXPECT_TRUE(got.has_depth && got.has_color);
      EXPECT_EQ(got.depth, fresh.depth) << "frame " << kFrameIndices[k] << " camera " << c;
      EXPECT_EQ(got.color, fresh.color) << "frame " << kFrameIndices[k] << " camera " << c;
    }
  }
  std::printf("decoding: at most %lld allocations a frame set after one pass\n", most);
}

// Called in the first sink call: holds it until the reconstruction has taken `sets` frame sets to
// make meshes of (counted in `made`; waiting at most `most_ms`), then a little longer, since the last one's reconstruction takes its
// mesh as it starts, right after it is counted, and this mesh must not have come back by then. So
// every mesh the pipeline can hold at once is made, whatever the threads' pace.
void hold_until_made(const std::atomic<int>& made, int sets, int most_ms) {
  for (int waited_ms = 0; made < sets && waited_ms < most_ms; ++waited_ms) std::this_thread::sleep_for(std::chrono::milliseconds(1));
  std::this_thread::sleep_for(std::chrono::milliseconds(100));
}

// The whole pipeline (run_pipeline: the source thread decoding, the reconstruction, the sink
// thread) over frame sets 0, 10 and 20 six times round, zipper without the filter: in the last two
// rounds nothing is allocated between one sink call and the next, counted on every thread. Frame
// sets come back to the source (run_pipeline's spares), meshes to the reconstructor, and the
// queues are rings of fixed size. The first sink call waits until the reconstruction has taken
// its fourth frame set (and a little longer), so that every mesh the pipeline can hold at once is
// made early (one in the sink, two queued, one being built), whatever the threads' pace. Before the
// reconstructor kept four meshes (not three), handed out the one kept longest (not the last one
// back) and grew it to the largest, six runs of five rounds (without the wait or the changes of
// pace) allocated 1, 1, 0, 3, 0 and 0 times after the second round; with them, four runs of this
// test allocated 6 times each, between the sink calls of frame sets 14 and 15.
TEST_F(SteadyState, PipelineAllocatesNothing) {
  const Capture capture = Capture::open(kSamba);
  FrameSetReader reader(capture);
  constexpr int kRounds = 6, kSets = 3 * kRounds;
  int next = 0;
  // In the measured rounds the pace changes as it does live: decoding stalls before frame set 13
  // (the reconstruction waits; every mesh comes back), then the sink is slow for frame sets 14 and
  // 15 (the queue to it fills; every mesh is needed again).
  constexpr int kStalledSource = 13, kSlowSinks[2] = {14, 15};
  const FrameSource source = [&](FrameSet& set, double& decode_ms) {
    if (next >= kSets) return false;
    if (next == kStalledSource) std::this_thread::sleep_for(std::chrono::milliseconds(300));
    reader.read(kFrameIndices[next++ % 3], set);
    decode_ms = 0;
    return true;
  };
  std::atomic<int> taken = 0;
  PipelineOptions options;
  options.before_reconstruct = [&](const FrameSet&, FrameReconstructor&) { ++taken; };
  FrameReconstructor reconstructor(read_rig(kSamba / "ground_truth" / "rig.json"), {.mode = ReconstructMode::kZipper, .bilateral = false});
  std::vector<long long> at_sink(kSets, -1);  // allocations so far, as each frame set reaches the sink
  std::vector<int> triangles(kSets, 0);
  int sunk = 0;
  const PipelineStats stats = run_pipeline(
      source, reconstructor,
      [&](PipelineFrame& frame) {
        at_sink[sunk] = g_allocations.load();
        triangles[sunk] = static_cast<int>(frame.result.mesh.triangle_count());
        if (sunk == 0) hold_until_made(taken, options.queue_depth + 2, 60000);
        if (sunk == kSlowSinks[0] || sunk == kSlowSinks[1]) std::this_thread::sleep_for(std::chrono::milliseconds(150));
        ++sunk;
      },
      options);
  EXPECT_GE(taken, options.queue_depth + 2);
  ASSERT_EQ(stats.frames, kSets);
  ASSERT_EQ(sunk, kSets);
  for (int k = 0; k < kSets; ++k) EXPECT_EQ(triangles[k], triangles[k % 3]) << "frame set " << k << ": the same input made another mesh";
  EXPECT_GT(triangles[0], 100000);
  const int first_measured = 4 * 3 - 1;  // the sink call ending the fourth round
  for (int k = first_measured + 1; k < kSets; ++k) {
    EXPECT_EQ(at_sink[k] - at_sink[k - 1], 0) << "between the sink calls of frame sets " << k - 1 << " and " << k;
  }
  std::printf("pipeline: %lld allocations from frame set %d's sink call to frame set %d's\n", at_sink[kSets - 1] - at_sink[first_measured],
              first_measured, kSets - 1);
}

// Background registration's hand-over copies a frame set into its window on the pipeline's thread
// (every --register-every frame sets): once the window is full, into the images of the set it
// drops. Counted on this thread only: the worker allocates as it refines, on its own. Before
// (2026-12-07), each hand-over copied into new images (8 of them, about 6 MB).
TEST_F(SteadyState, BackgroundRegistrationsHandOverAllocatesNothing) {
  constexpr int kWindow = 2, kOffers = 7;
  BackgroundRegistration registration(read_rig(kSamba / "ground_truth" / "rig.json"),
                                      {.every_frames = 1, .window_frames = kWindow});
  std::vector<long long> allocations;
  for (int k = 0; k < kOffers; ++k) {
    registration.wait_idle();  // so the offer is taken, not skipped
    const long long before = t_allocations;
    registration.offer(frames_[k % 3]);
    allocations.push_back(t_allocations - before);
  }
  registration.wait_idle();
  for (int k = 0; k < kWindow; ++k) EXPECT_GT(allocations[k], 0) << "offer " << k << ": filling the window copies";
  for (int k = kWindow; k < kOffers; ++k) EXPECT_EQ(allocations[k], 0) << "offer " << k;
  EXPECT_EQ(registration.latest_poses()->world_from_depth.size(), 4u);
}

// A live command's pipeline and reconstruction, as the live allocation test below runs them.
struct LiveCommand {
  const char* name;
  PipelineOptions pipeline;
  ReconstructOptions reconstruction;
  int skip_period;  // the sink is not ready for one set in this many (wants_frame); 0: ready for all
  int most_meshes;  // meshes the pipeline can hold at once
};
void PrintTo(const LiveCommand& command, std::ostream* out) { *out << command.name; }

// `reconstruct --live` (without the filter, the zipper's heaviest case): the default queues,
// every set reconstructed; one mesh in the sink, `queue_depth` queued, one being built.
LiveCommand reconstruct_live() {
  PipelineOptions pipeline;
  pipeline.source_policy = QueuePolicy::kDropOldest;
  return {"reconstruct_live", pipeline, {.mode = ReconstructMode::kZipper, .bilateral = false}, 0, pipeline.queue_depth + 2};
}
// `serve --live` (serve_command.cc), with serve's defaults: the bilateral filter at level of detail
// 1. One set queued; the next set is taken only once the sink has taken the last mesh, so one mesh
// is in the sink and one queued, none built meanwhile; sets no viewer is ready for are skipped
// unreconstructed. Skipping one in four, a period prime to the dumps' three frames, lets every
// dump frame through however regular the pace.
constexpr int kServeSkipPeriod = 4;
LiveCommand serve_live() {
  PipelineOptions pipeline;
  pipeline.source_policy = QueuePolicy::kDropOldest;
  pipeline.queue_depth = 1;
  pipeline.take_when_sink_ready = true;
  return {"serve_live", pipeline, {.mode = ReconstructMode::kZipper, .bilateral = true, .depth_level = 1}, kServeSkipPeriod, pipeline.queue_depth + 1};
}

class LiveSteadyState : public testing::TestWithParam<LiveCommand> {};

// Live cameras: four fakenect dumps of the synthetic ring, replayed in a loop as the devices
// delivered them (paced), through LiveRig and live_frame_source into the pipeline, with the
// pipeline and reconstruction of `reconstruct --live` and of `serve --live` (LiveCommand): the
// source drops its oldest set rather than wait, so which sets are reconstructed depends on the
// threads' pace. The images go round from the pipeline's recycled frame sets back through the rig
// to the cameras (LiveFrameQueue for a device, the replay's own buffers here), so once every
// buffer has grown nothing is allocated between sink calls. Every buffer grows only once the
// pipeline has been through the changes of pace that need the most of them, so the warm-up goes
// through them too: the first sink call waits until the pipeline holds every mesh it can
// (`most_meshes`); the source then stalls, and as it catches up with the reconstruction busy,
// every frame set the queues allow exists (one being filled, `queue_depth` queued, one being
// reconstructed). A mesh grows to the largest frame set's when it is next taken, so the
// measurement starts eight sink calls after every frame of the dumps has been reconstructed. Then
// the pace changes again: the source stalls, then the sink is slow twice, and after 30 measured
// sink calls the rig is stopped.
// Before (2026-12-07), each camera's frame took new images and the rig a new set, a grouping
// decision and a view of the streams. This test's first version (blocking policy, unpaced, no
// change of pace, measured from the fourth pass) failed once in CI under load (1 and 2
// allocations, probably one of these): a slow sink after its warm-up cost 6 allocations (a fourth
// mesh's), a stalled live source 9 (a fourth frame set's), a mesh still growing 3. Until then only
// `reconstruct --live`'s pipeline was measured.
TEST_P(LiveSteadyState, ReplayedCamerasToSinkAllocateNothing) {
  const fs::path dir = fs::temp_directory_path() / "zf_steady_state_live";
  fs::remove_all(dir);
  constexpr int kCameras = 4, kDumpFrames = 3;
  constexpr int kWarmSinkCalls = 8;       // after every dump frame has reached the sink
  constexpr size_t kMeasuredSteps = 30;   // sink calls measured; the rig is then stopped
  constexpr int kMostSets = 1000;         // a bound, should the sink never get that far
  const SynthOptions synth{.frames = kDumpFrames, .cameras = kCameras};
  std::vector<fs::path> dumps;
  Rig calibration;
  for (int c = 0; c < kCameras; ++c) {
    dumps.push_back(dir / ("cam" + std::to_string(c)));
    const FakenectSceneResult scene = write_fakenect_scene(dumps.back(), synth, {.camera = c});
    if (c == 0) calibration = scene.truth_rig;
    else calibration.cameras.push_back(scene.truth_rig.cameras[0]);
    calibration.cameras.back().name = "cam" + std::to_string(c);
  }
  const ReplayTimeline timeline = replay_timeline(dumps, synth.fps);
  std::vector<std::unique_ptr<LiveCamera>> cameras;
  for (int c = 0; c < kCameras; ++c) {
    cameras.push_back(std::make_unique<ReplayCamera>(dumps[c], "cam" + std::to_string(c),
                                                     ReplayOptions{.loop = true, .paced = true, .timeline = timeline}));
  }
  LiveRig live(std::move(cameras));
  const Rig rig = make_live_rig(live, &calibration, "the synthetic ring's truth");
  const LiveCommand& command = GetParam();
  FrameReconstructor reconstructor(rig, command.reconstruction);
  struct Sunk {
    int index;              // the set's index from the source (dropped sets leave gaps)
    long sequence;          // sets the reconstruction took before it (skipped sets leave gaps)
    long long allocations;  // allocations so far, as the set reaches the sink
    int triangles, cameras_used;
  };
  std::vector<Sunk> sunk;
  sunk.reserve(kMostSets);
  std::vector<char> frame_seen(kDumpFrames, 0);
  int warm_sink_calls = -1;       // sink calls since every dump frame was seen, -1 before
  size_t first_measured = kMostSets;  // the sink call the measurement starts after
  std::atomic<bool> stall_source = false;
  std::atomic<int> made = 0;  // frame sets the reconstruction has taken to make a mesh of
  PipelineOptions options = command.pipeline;
  static_assert(std::gcd(kServeSkipPeriod, kDumpFrames) == 1, "serve_live's skipping must let every dump frame through");
  int offered = 0;  // sets the pipeline asked the sink about (wants_frame), on the reconstruction's thread
  if (command.skip_period > 0) {
    options.wants_frame = [&] {
      const bool wanted = offered++ % command.skip_period != command.skip_period - 1;
      if (wanted) ++made;
      return wanted;
    };
  } else {
    options.before_reconstruct = [&](const FrameSet&, FrameReconstructor&) { ++made; };
  }
  const LiveSourceOptions source_options{.max_frames = kMostSets, .observe = [&](const LiveFrameSet&) {
                                           if (stall_source.exchange(false)) std::this_thread::sleep_for(std::chrono::milliseconds(300));
                                         }};
  const PipelineStats stats = run_pipeline(
      live_frame_source(live, source_options), reconstructor,
      [&](PipelineFrame& frame) {
        sunk.push_back({static_cast<int>(frame.index), frame.sequence, g_allocations.load(),
                        static_cast<int>(frame.result.mesh.triangle_count()), frame.result.cameras_used});
        const size_t call = sunk.size() - 1;
        if (call == 0) hold_until_made(made, command.most_meshes, 10000);  // the source fills and drops meanwhile
        if (call == 1) stall_source = true;  // it then catches up, the reconstruction busy: every frame set the queues allow
        frame_seen[frame.index % kDumpFrames] = 1;
        if (warm_sink_calls < 0 && call >= 1 && std::ranges::count(frame_seen, 1) == kDumpFrames) warm_sink_calls = 0;
        if (warm_sink_calls >= 0 && ++warm_sink_calls == kWarmSinkCalls) first_measured = call;
        if (call == first_measured + 1) stall_source = true;
        if (call == first_measured + 4 || call == first_measured + 5) std::this_thread::sleep_for(std::chrono::milliseconds(150));
        // Stopped by progress, not after a number of sets: on a slow machine fewer sets reach the sink.
        if (call == first_measured + kMeasuredSteps) live.stop();
      },
      options);
  fs::remove_all(dir);
  ASSERT_EQ(stats.frames, static_cast<int>(sunk.size()));
  ASSERT_LT(first_measured + kMeasuredSteps, sunk.size()) << "too few frame sets reached the sink to measure (" << stats.dropped << " dropped)";
  // Up to the stop: the sets after it hold what the cameras had delivered, perhaps not all four.
  const size_t last = first_measured + kMeasuredSteps;
  // A dropped set is one the sink never sees; the rig itself skips no frame of the replay, so
  // set k holds the dumps' frame k % 3.
  std::vector<int> triangles_of_frame(kDumpFrames, -1);
  for (size_t i = 0; i <= last; ++i) {
    const Sunk& s = sunk[i];
    EXPECT_EQ(s.cameras_used, kCameras) << "frame set " << s.index;
    int& expected = triangles_of_frame[s.index % kDumpFrames];
    if (expected < 0) expected = s.triangles;
    EXPECT_EQ(s.triangles, expected) << "frame set " << s.index << ": the same frames made another mesh";
  }
  EXPECT_GT(triangles_of_frame[0], command.reconstruction.depth_level == 0 ? 50000 : 20000);
  long skipped = 0;  // sets skipped unreconstructed while measured
  for (size_t i = first_measured + 1; i <= last; ++i) skipped += sunk[i].sequence - sunk[i - 1].sequence - 1;
  if (command.skip_period > 0) {
    EXPECT_GT(skipped, 0) << "no set was skipped while measured";
  } else {
    EXPECT_EQ(skipped, 0);
  }
  for (size_t i = first_measured + 1; i <= last; ++i) {
    EXPECT_EQ(sunk[i].allocations - sunk[i - 1].allocations, 0) << "between the sink calls of frame sets " << sunk[i - 1].index << " and "
                                                                << sunk[i].index;
  }
  std::printf("live (%s): %zu frame sets reached the sink (%ld dropped, %ld skipped, %ld while measured), %d triangles from the dumps' "
              "first frame; %lld allocations over %zu measured steps\n",
              command.name, sunk.size(), stats.dropped, stats.unwanted, skipped, triangles_of_frame[0],
              sunk[last].allocations - sunk[first_measured].allocations, kMeasuredSteps);
}

INSTANTIATE_TEST_SUITE_P(, LiveSteadyState, testing::Values(reconstruct_live(), serve_live()),
                         [](const testing::TestParamInfo<LiveCommand>& param_info) { return std::string(param_info.param.name); });

}  // namespace
}  // namespace zipfusion
