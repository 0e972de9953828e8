// KinectCamera through libfreenect's fakenect (the replacement library that plays a dump through
// the libfreenect API, as `fakenect DUMP PROGRAM` runs it): a steady stream read through LiveRig
// and the live source into two frame sets in turn allocates nothing once its images go round
// (every operator new of this binary is counted, the event thread's callback included; fakenect's
// own reading is C, not counted). The test writes a dump of the synthetic scene, then runs this
// binary again under `fakenect`, where the same test reads the device.

#include "zipfusion/live/kinect_camera.h"

#include <gtest/gtest.h>

#include <chrono>
#include <cstdio>
#include <cstdlib>
#include <filesystem>
#include <string>
#include <thread>
#include <unistd.h>
#include <vector>

#include "zipfusion/core/allocation_count_test_util.h"
#include "zipfusion/live/live_rig.h"
#include "zipfusion/synth/fakenect_scene.h"

namespace zipfusion {
namespace {

namespace fs = std::filesystem;

constexpr int kDumpFrames = 40, kWarmUpSets = 10;
// The reader stalls twice: in the warm-up for about five frames, which queue meanwhile, each in
// images of its own, of which the queue keeps four frames' worth for the next backlog; after it
// for about two. A reader that had not fallen behind in the warm-up can allocate at its first
// stall after it (2 allocations after a 100 ms stall, in one run alone and in one of five beside
// three CPU hogs); one whose later backlog outgrows what the queue keeps would too.
constexpr int kStalledSets[2] = {4, 20};
constexpr int kStallMs[2] = {160, 60};

// Under fakenect: the device's frames through the rig and the live source.
void read_device_and_count() {
  LiveRig live(open_kinect_cameras("all"));
  LiveFrameSource source = live_frame_source(live);
  FrameSet sets[2];
  std::vector<long long> allocations;  // per frame set after the warm-up
  allocations.reserve(kDumpFrames);
  int delivered = 0, with_depth = 0, with_color = 0;
  for (double decode_ms = 0;; ++delivered) {
    const long long before = g_allocations.load();
    for (int k = 0; k < 2; ++k) {
      if (delivered == kStalledSets[k]) std::this_thread::sleep_for(std::chrono::milliseconds(kStallMs[k]));
    }
    if (!source(sets[delivered % 2], decode_ms)) break;
    if (delivered >= kWarmUpSets) allocations.push_back(g_allocations.load() - before);
    const CameraFrame& camera = sets[delivered % 2].cameras.at(0);
    with_depth += camera.has_depth && camera.depth.width == 640 && camera.depth.height == 480;
    with_color += camera.has_color && camera.color.width == 640;
  }
  EXPECT_GE(delivered, kDumpFrames - 2) << live.stats()[0].end_reason;  // fakenect may end on the last frames
  EXPECT_EQ(with_depth, delivered);
  EXPECT_GE(with_color, delivered - 1);
  // The last set is read while the stream ends: the end's reason ("end of the fakenect recording")
  // is a string made then, on the event thread.
  if (!allocations.empty()) allocations.pop_back();
  long long total = 0;
  for (size_t k = 0; k < allocations.size(); ++k) {
    EXPECT_EQ(allocations[k], 0) << "frame set " << kWarmUpSets + k;
    total += allocations[k];
  }
  std::printf("kinect under fakenect: %lld allocations in %zu frame sets after %d\n", total, allocations.size(), kWarmUpSets);
}

TEST(KinectUnderFakenect, ASteadyStreamAllocatesNothing) {
  if (std::getenv("FAKENECT_PATH") != nullptr) {
    read_device_and_count();
    return;
  }
  ASSERT_EQ(std::system("command -v fakenect > /dev/null"), 0) << "no fakenect: libfreenect-bin, which scripts/install-deps.sh installs";
  const fs::path dir = fs::temp_directory_path() / ("zf_kinect_camera_test_" + std::to_string(::getpid()));
  fs::remove_all(dir);
  write_fakenect_scene(dir / "dump", SynthOptions{.frames = kDumpFrames}, {});
  const std::string self = fs::read_symlink("/proc/self/exe").string();
  const std::string log = (dir / "child.log").string();
  const int status = std::system(("fakenect '" + (dir / "dump").string() + "' '" + self +
                                  "' --gtest_filter=KinectUnderFakenect.ASteadyStreamAllocatesNothing > '" + log + "' 2>&1")
                                     .c_str());
  std::string output;
  if (FILE* f = std::fopen(log.c_str(), "r")) {
    char buffer[4096];
    for (size_t n; (n = std::fread(buffer, 1, sizeof buffer, f)) > 0;) output.append(buffer, n);
    std::fclose(f);
  }
  fs::remove_all(dir);
  EXPECT_EQ(status, 0) << output;
  EXPECT_NE(output.find("kinect under fakenect: 0 allocations"), std::string::npos) << output;
}

}  // namespace
}  // namespace zipfusion
