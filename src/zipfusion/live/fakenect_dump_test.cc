#include "zipfusion/live/fakenect_dump.h"

#include <gtest/gtest.h>

#include <chrono>
#include <cmath>

#include <filesystem>
#include <random>
#include <thread>

#include "zipfusion/core/error.h"
#include "zipfusion/core/error_test_util.h"
#include "zipfusion/core/folder_test_util.h"
#include "zipfusion/io/file_util.h"
#include "zipfusion/live/kinect_disparity.h"
#include "zipfusion/live/replay_camera.h"

namespace zipfusion {
namespace {

namespace fs = std::filesystem;

RawDepthImage ramp_raw(int seed) {
  RawDepthImage raw(kFakenectWidth, kFakenectHeight);
  for (int v = 0; v < raw.height; ++v) {
    for (int u = 0; u < raw.width; ++u) raw(u, v) = (u + v) % 11 == 0 ? kKinectRawNoValue : static_cast<std::uint16_t>(400 + (u + 2 * v + seed) % 600);
  }
  return raw;
}

ColorImage pattern_rgb(int seed) {
  ColorImage c(kFakenectWidth, kFakenectHeight);
  for (int v = 0; v < c.height; ++v) {
    for (int u = 0; u < c.width; ++u) {
      c(u, v) = {static_cast<unsigned char>(u + seed), static_cast<unsigned char>(v * 3), static_cast<unsigned char>(u ^ v)};
    }
  }
  return c;
}

class FakenectDump : public FolderTest {
 protected:
  FakenectDump() : FolderTest("zf_fakenect_dump_test_") {}

  // A dump of `frames` frames as synth --fakenect lays it out: colour, then depth 1 ms later.
  std::vector<FakenectIndexEntry> write_dump(int frames) {
    std::vector<FakenectIndexEntry> index;
    for (int i = 0; i < frames; ++i) {
      const double t = 1700000000.0 + i / 30.0;
      FakenectIndexEntry color{.type = 'r', .time_s = t, .timestamp = static_cast<std::uint32_t>(940000 + 2000000 * i), .file = ""};
      FakenectIndexEntry depth{.type = 'd', .time_s = t + 0.001, .timestamp = static_cast<std::uint32_t>(1000000 + 2000000 * i), .file = ""};
      color.file = fakenect_file_name('r', color.time_s, color.timestamp);
      depth.file = fakenect_file_name('d', depth.time_s, depth.timestamp);
      write_fakenect_file(dir_, color, encode_fakenect_rgb(pattern_rgb(i)));
      write_fakenect_file(dir_, depth, encode_fakenect_depth(ramp_raw(i)));
      index.push_back(color);
      index.push_back(depth);
    }
    write_fakenect_index(dir_, index);
    return index;
  }
};

TEST(FakenectFormat, FileNamesAreFakenectRecords) {
  EXPECT_EQ(fakenect_file_name('d', 1700000000.033333, 2000000), "d-1700000000.033333-2000000.pgm");
  EXPECT_EQ(fakenect_file_name('r', 12.5, 7), "r-12.500000-7.ppm");
}

TEST(FakenectFormat, IndexParsesTypeTimeAndTimestamp) {
  const std::vector<FakenectIndexEntry> entries =
      parse_fakenect_index("r-1294185715.129114-3565587864.ppm\r\nd-1294185715.130000-3565601952.pgm\n\na-1294185715.131-3565601952.dump\n"
                           "d-5.25-77-extra.pgm\n",
                           "INDEX.txt");
  ASSERT_EQ(entries.size(), 4u);
  EXPECT_EQ(entries[0].type, 'r');
  EXPECT_DOUBLE_EQ(entries[0].time_s, 1294185715.129114);
  EXPECT_EQ(entries[0].timestamp, 3565587864u);
  EXPECT_EQ(entries[0].file, "r-1294185715.129114-3565587864.ppm");
  EXPECT_EQ(entries[1].type, 'd');
  EXPECT_EQ(entries[1].timestamp, 3565601952u);
  EXPECT_EQ(entries[2].type, 'a');
  EXPECT_DOUBLE_EQ(entries[3].time_s, 5.25);  // fakenect's own pattern "%c-%lf-%u-%*s"
  EXPECT_EQ(entries[3].timestamp, 77u);
}

TEST(FakenectFormat, MalformedIndexLinesAreNamed) {
  // Longer than any file name (255 bytes): it names no file.
  const std::string too_long = "d-1.0-12.pgm\nd-1.0-12-" + std::string(300, 'x') + ".pgm\n";
  // A NUL byte for the type (libFuzzer found it: the name fakenect would be given was cut short),
  // a digit, a space, an escape: names that scanf's %s or the file system would not read back.
  const std::string nul_type = std::string("d-1.0-12.pgm\n") + '\0' + "-1.0-12.pgm\n";
  for (const std::string& bad : {std::string("d-1.0-12.pgm\nnot-a-name\n"), std::string("d-1.0-12.pgm\nd-x-12.pgm\n"),
                                 std::string("d-1.0-12.pgm\nd-1.0-.pgm\n"), std::string("d-1.0-12.pgm\nd-1.0-99999999999.pgm\n"),
                                 std::string("d-1.0-12.pgm\nd-1.0-12/../x.pgm\n"),
                                 // Times that are no recording's: grouping frames at them never ended.
                                 std::string("d-1.0-12.pgm\nd-nan-12.pgm\n"), std::string("d-1.0-12.pgm\nd-inf-12.pgm\n"),
                                 std::string("d-1.0-12.pgm\nd-1e300-12.pgm\n"), std::string("d-1.0-12.pgm\nd--5.0-12.pgm\n"), too_long,
                                 nul_type, std::string("d-1.0-12.pgm\n5-1.0-12.pgm\n"), std::string("d-1.0-12.pgm\nd-1.0-12 x.pgm\n"),
                                 std::string("d-1.0-12.pgm\nd-1.0-12.p\x1bgm\n")}) {
    const std::string message = invalid_input_message([&] { parse_fakenect_index(bad, "dump/INDEX.txt"); });
    EXPECT_NE(message.find("dump/INDEX.txt: line 2:"), std::string::npos) << ::testing::PrintToString(bad) << ": " << message;
  }
}

// A binary file given as INDEX.txt is quoted with its bytes escaped and cut short, not printed raw.
TEST(FakenectFormat, BinaryIndexIsQuotedPrintably) {
  std::string binary = "d-1.0-12.pgm\n\x01\x89PNG";
  binary += std::string(200, '\xff');
  const std::string message = invalid_input_message([&] { parse_fakenect_index(binary, "dump/INDEX.txt"); });
  EXPECT_NE(message.find("dump/INDEX.txt: line 2: \"\\x01\\x89PNG\\xff"), std::string::npos) << message;
  EXPECT_NE(message.find("...\" is not a fakenect file name"), std::string::npos) << message;
  for (const char c : message) EXPECT_TRUE(c >= 0x20 && c < 0x7f) << message;
}

TEST(FakenectFormat, DepthAndColourRoundTripBitExactly) {
  const RawDepthImage raw = ramp_raw(3);
  const std::vector<std::uint8_t> bytes = encode_fakenect_depth(raw);
  const std::string header = "P5 640 480 65535\n";
  ASSERT_EQ(bytes.size(), header.size() + 640u * 480 * 2);
  EXPECT_EQ(std::string(bytes.begin(), bytes.begin() + header.size()), header);
  // Little-endian, as libfreenect's buffer on the host: pixel 1 holds 400 + (1 + 3) % 600 = 404.
  EXPECT_EQ(bytes[header.size() + 2], 404 & 0xff);
  EXPECT_EQ(bytes[header.size() + 3], 404 >> 8);
  EXPECT_EQ(decode_fakenect_depth(bytes, "d.pgm"), raw);

  const ColorImage rgb = pattern_rgb(5);
  const std::vector<std::uint8_t> rgb_bytes = encode_fakenect_rgb(rgb);
  EXPECT_EQ(std::string(rgb_bytes.begin(), rgb_bytes.begin() + 15), "P6 640 480 255\n");
  EXPECT_EQ(rgb_bytes.size(), 15u + 640 * 480 * 3);
  EXPECT_EQ(decode_fakenect_rgb(rgb_bytes, "r.ppm"), rgb);
}

// A PGM that is no fakenect depth frame: another MAXVAL, or 16-bit values past the Kinect's 11 bits
// (a big-endian PGM read in fakenect's little-endian order) were recorded without a word.
TEST(FakenectFormat, DepthThatIsNotElevenBitIsAnError) {
  std::vector<std::uint8_t> bytes = encode_fakenect_depth(ramp_raw(0));
  std::vector<std::uint8_t> other_maxval = bytes;
  std::copy_n("P5 640 480 00000", 16, other_maxval.begin());
  const size_t header = std::string("P5 640 480 65535\n").size();
  std::swap(bytes[header + 2], bytes[header + 3]);  // pixel 1 (401) byte-swapped: 37121
  const std::pair<const std::vector<std::uint8_t>*, const char*> cases[] = {{&other_maxval, "d.pgm: header: MAXVAL is 0, fakenect writes 65535"},
                                                                            {&bytes, "d.pgm: pixels: value 37121 above 2047"}};
  for (const auto& [file, expected] : cases) {
    const std::string message = invalid_input_message([&] { decode_fakenect_depth(*file, "d.pgm"); });
    EXPECT_NE(message.find(expected), std::string::npos) << "expected: " << expected << "\n  actual: " << message;
  }
}

TEST(FakenectFormat, TruncatedOrWrongFilesAreErrorsNamingThem) {
  std::vector<std::uint8_t> bytes = encode_fakenect_depth(ramp_raw(0));
  bytes.pop_back();
  EXPECT_EQ(invalid_input_message([&] { decode_fakenect_depth(bytes, "dump/d-1.pgm"); }), "dump/d-1.pgm: truncated: 614399 of 614400 bytes");
  EXPECT_THROW(decode_fakenect_rgb(encode_fakenect_depth(ramp_raw(0)), "r.ppm"), InvalidInput);  // P5 is not P6
  const std::string small = "P5 320 240 65535\n";
  EXPECT_THROW(decode_fakenect_depth(std::vector<std::uint8_t>(small.begin(), small.end()), "d.pgm"), InvalidInput);
  EXPECT_THROW(decode_fakenect_depth(std::vector<std::uint8_t>(100, 'x'), "d.pgm"), InvalidInput);  // no newline
}

TEST(FakenectFormat, DecodersNeverCrashOnRandomBytes) {
  std::mt19937 rng(7);
  int rejected = 0;
  for (int i = 0; i < 300; ++i) {
    std::vector<std::uint8_t> bytes(rng() % 64);
    for (auto& b : bytes) b = static_cast<std::uint8_t>(rng());
    if (i % 3 == 0) {
      const std::string header = i % 2 ? "P5 640 480 65535\n" : "P6 640 4";
      bytes.insert(bytes.begin(), header.begin(), header.end());
    }
    if (invalid_input_message([&] { decode_fakenect_depth(bytes, "x"); }) != kNoInvalidInput) ++rejected;
    if (invalid_input_message([&] { decode_fakenect_rgb(bytes, "x"); }) != kNoInvalidInput) ++rejected;
  }
  EXPECT_EQ(rejected, 600);
}

TEST_F(FakenectDump, WriterAndIndexRoundTrip) {
  const std::vector<FakenectIndexEntry> written = write_dump(3);
  const std::vector<FakenectIndexEntry> read = read_fakenect_index(dir_);
  ASSERT_EQ(read.size(), written.size());
  for (size_t i = 0; i < read.size(); ++i) {
    EXPECT_EQ(read[i].file, written[i].file);
    EXPECT_EQ(read[i].type, written[i].type);
    EXPECT_EQ(read[i].timestamp, written[i].timestamp);
    EXPECT_NEAR(read[i].time_s, written[i].time_s, 1e-6);  // %f: microseconds
  }
  EXPECT_EQ(decode_fakenect_depth(read_file_bytes(dir_ / read[3].file), "d"), ramp_raw(1));
}

TEST_F(FakenectDump, ReplayCameraDeliversMillimetresColourAndTimestamps) {
  write_dump(3);
  ReplayCamera camera(dir_, "cam0");
  EXPECT_EQ(camera.model().depth_intrinsics.fx, 580);
  EXPECT_EQ(camera.model().color_intrinsics->fx, 525);
  EXPECT_NEAR(camera.model().color_from_depth.translation().x(), -0.025, 1e-12);
  for (int i = 0; i < 3; ++i) {
    LiveFrame frame;
    ASSERT_EQ(camera.read(frame, 0), ReadStatus::kFrame) << i;
    EXPECT_EQ(frame.device_timestamp, 1000000u + 2000000u * i);
    EXPECT_NEAR(frame.time_s, 1700000000.001 + i / 30.0, 2e-6);
    const RawDepthImage raw = ramp_raw(i);
    ASSERT_EQ(frame.depth.width, 640);
    int valid = 0;
    for (size_t p = 0; p < raw.data.size(); ++p) {
      ASSERT_EQ(frame.depth.data[p], kinect_raw_to_mm(raw.data[p]));
      valid += frame.depth.data[p] != 0;
    }
    EXPECT_EQ(valid, 279273);  // 640·480 less the (u + v) % 11 == 0 holes
    ASSERT_TRUE(frame.has_color);
    EXPECT_EQ(frame.color, pattern_rgb(i));
  }
  LiveFrame frame;
  EXPECT_EQ(camera.read(frame, 0), ReadStatus::kEnded);
  EXPECT_EQ(camera.end_reason(), "end of the recording (6 files in INDEX.txt)");
}

TEST_F(FakenectDump, ATruncatedLastFileEndsTheStreamAfterTheGoodFrames) {
  const std::vector<FakenectIndexEntry> index = write_dump(3);
  const fs::path last = dir_ / index.back().file;
  fs::resize_file(last, 1000);
  ReplayCamera camera(dir_, "cam0");
  LiveFrame frame;
  EXPECT_EQ(camera.read(frame, 0), ReadStatus::kFrame);
  EXPECT_EQ(camera.read(frame, 0), ReadStatus::kFrame);
  EXPECT_EQ(camera.read(frame, 0), ReadStatus::kEnded);
  EXPECT_EQ(camera.end_reason(), last.string() + ": truncated: 983 of 614400 bytes: the recording ends here");
  EXPECT_EQ(camera.read(frame, 0), ReadStatus::kEnded);
}

TEST_F(FakenectDump, PlayableEntriesEndAtTheFirstMissingOrShortFile) {
  const std::vector<FakenectIndexEntry> index = write_dump(3);
  std::string problem;
  EXPECT_EQ(fakenect_playable_entries(dir_, index, problem), 6u);
  EXPECT_EQ(problem, "");
  fs::resize_file(dir_ / index[5].file, 614400);  // header + 614400 would be whole
  EXPECT_EQ(fakenect_playable_entries(dir_, index, problem), 5u);
  EXPECT_EQ(problem, (dir_ / index[5].file).string() + ": truncated: 614400 of 614417 bytes");
  fs::remove(dir_ / index[2].file);
  EXPECT_EQ(fakenect_playable_entries(dir_, index, problem), 2u);
  EXPECT_EQ(problem, (dir_ / index[2].file).string() + ": missing");
}

TEST_F(FakenectDump, ColourIsPairedByTheDevicesClock) {
  // The only colour, then depth the device stamped `ticks` later (60 MHz) and the host wrote down
  // `host_s` later: paired by the device's stamps alone, within 40 ms.
  auto paired = [&](std::uint32_t ticks, double host_s) {
    fs::remove_all(dir_);
    fs::create_directories(dir_);
    const FakenectIndexEntry color{.type = 'r', .time_s = 10.0, .timestamp = 1000, .file = fakenect_file_name('r', 10.0, 1000)};
    const FakenectIndexEntry depth{.type = 'd', .time_s = 10.0 + host_s, .timestamp = 1000 + ticks,
                                   .file = fakenect_file_name('d', 10.0 + host_s, 1000 + ticks)};
    write_fakenect_file(dir_, color, encode_fakenect_rgb(pattern_rgb(0)));
    write_fakenect_file(dir_, depth, encode_fakenect_depth(ramp_raw(0)));
    write_fakenect_index(dir_, {color, depth});
    ReplayCamera camera(dir_, "cam0");
    LiveFrame frame;
    EXPECT_EQ(camera.read(frame, 0), ReadStatus::kFrame);
    return frame.has_color;
  };
  EXPECT_FALSE(paired(6000000, 0.001));  // 0.1 s apart on the device, 1 ms apart on the host
  EXPECT_TRUE(paired(60000, 0.1));       // 1 ms apart on the device, 0.1 s on a busy host
  EXPECT_TRUE(paired(2399999, 0.04));
  EXPECT_FALSE(paired(2400001, 0.04));
}

// Looped, a dump plays again and again on one time line: pass k's times are the recording's
// shifted by k passes (from the first entry to one frame period past the last), so that they
// keep rising, and colour still pairs with depth by the device clock.
TEST_F(FakenectDump, ALoopedReplayPlaysAgainWithRisingTimes) {
  write_dump(3);
  const ReplayTimeline timeline = replay_timeline({dir_}, 30);
  const double period = (1700000000.0 + 2 / 30.0 + 0.001) - 1700000000.0 + 1 / 30.0;  // last depth − first colour + a frame
  EXPECT_NEAR(timeline.first_s, 1700000000.0, 1e-6);
  EXPECT_NEAR(timeline.period_s, period, 2e-6);
  ReplayCamera camera(dir_, "cam0", ReplayOptions{.loop = true, .timeline = timeline});
  const auto pass_ticks = static_cast<std::uint32_t>(std::llround(timeline.period_s * 60e6));
  for (int k = 0; k < 8; ++k) {
    const int i = k % 3, pass = k / 3;
    LiveFrame frame;
    ASSERT_EQ(camera.read(frame, 0), ReadStatus::kFrame) << k;
    EXPECT_NEAR(frame.time_s, 1700000000.001 + i / 30.0 + pass * timeline.period_s, 2e-6) << k;
    EXPECT_EQ(frame.device_timestamp, 1000000u + 2000000u * i + pass * pass_ticks) << k;
    ASSERT_TRUE(frame.has_color) << k;
    EXPECT_EQ(frame.color, pattern_rgb(i)) << k;
  }
  camera.stop();
  LiveFrame frame;
  EXPECT_EQ(camera.read(frame, 0), ReadStatus::kEnded);
  EXPECT_EQ(camera.read(frame, 0), ReadStatus::kEnded);  // and stays ended
  EXPECT_EQ(camera.end_reason(), "stopped");
}

// A loop over a dump without depth ends instead of spinning.
TEST_F(FakenectDump, ALoopWithoutDepthEnds) {
  std::vector<FakenectIndexEntry> index = write_dump(2);
  std::erase_if(index, [](const FakenectIndexEntry& e) { return e.type == 'd'; });
  write_fakenect_index(dir_, index);
  ReplayCamera camera(dir_, "cam0", ReplayOptions{.loop = true, .timeline = replay_timeline({dir_}, 30)});
  LiveFrame frame;
  EXPECT_EQ(camera.read(frame, 0), ReadStatus::kEnded);
  EXPECT_EQ(camera.end_reason(), "end of the recording (2 files in INDEX.txt)");
}

// Paced, a frame recorded at t comes no sooner than t − first after the time line's start, and a
// read whose timeout ends before then times out and keeps the frame for the next read.
TEST_F(FakenectDump, APacedReplayDeliversAtTheRecordedTimes) {
  write_dump(4);
  ReplayTimeline timeline = replay_timeline({dir_}, 30);
  timeline.start = std::make_shared<ReplayStart>(std::chrono::steady_clock::now() + std::chrono::seconds(30));  // not due for a long while
  {
    ReplayCamera later(dir_, "cam0", ReplayOptions{.paced = true, .timeline = timeline});
    LiveFrame frame;
    EXPECT_EQ(later.read(frame, 0.05), ReadStatus::kTimeout);
    EXPECT_EQ(later.read(frame, 0), ReadStatus::kTimeout);
    // Stopped from another thread while a read waits: that read delivers the frame it had read
    // at once (as a device's queued frames are), not after the 30 s, and the stream ends.
    const auto asked = std::chrono::steady_clock::now();
    std::thread stopper([&later] {
      std::this_thread::sleep_for(std::chrono::milliseconds(100));
      later.stop();
    });
    EXPECT_EQ(later.read(frame, 60), ReadStatus::kFrame);
    stopper.join();
    EXPECT_NEAR(frame.time_s, 1700000000.001, 2e-6);
    EXPECT_EQ(later.read(frame, 60), ReadStatus::kEnded);
    EXPECT_EQ(later.end_reason(), "stopped");
    EXPECT_LT(std::chrono::steady_clock::now() - asked, std::chrono::seconds(20));
  }
  // Without a given start, the time line starts at the first read, not when the cameras were
  // made: a rig read a while after it was opened (a server starting) gets no burst of frames.
  timeline.start = std::make_shared<ReplayStart>();
  ReplayCamera camera(dir_, "cam0", ReplayOptions{.paced = true, .timeline = timeline});
  ReplayCamera other(dir_, "cam1", ReplayOptions{.paced = true, .timeline = timeline});
  std::this_thread::sleep_for(std::chrono::milliseconds(300));
  const auto first_read = std::chrono::steady_clock::now();
  for (int i = 0; i < 4; ++i) {
    LiveFrame frame;
    ASSERT_EQ(camera.read(frame, 10), ReadStatus::kFrame) << i;
    const double since_first_read = std::chrono::duration<double>(std::chrono::steady_clock::now() - first_read).count();
    EXPECT_NEAR(frame.time_s, 1700000000.001 + i / 30.0, 2e-6) << i;
    EXPECT_GE(since_first_read, frame.time_s - timeline.first_s) << i;
  }
  // The other camera shares that start: its first frame, read now, is long due.
  LiveFrame frame;
  EXPECT_EQ(other.read(frame, 0), ReadStatus::kFrame);
  // Set by the first read, after first_read; set when the cameras were made, it would lie 300 ms
  // before it.
  EXPECT_GE(timeline.start->at(), first_read);
}

TEST_F(FakenectDump, StopEndsTheReplay) {
  write_dump(2);
  ReplayCamera camera(dir_, "cam0");
  camera.stop();
  LiveFrame frame;
  EXPECT_EQ(camera.read(frame, 0), ReadStatus::kEnded);
  EXPECT_EQ(camera.end_reason(), "stopped");
}

}  // namespace
}  // namespace zipfusion
