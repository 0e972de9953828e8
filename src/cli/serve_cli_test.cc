// zipfusion serve from the command line: it streams a capture at its frame rate for the time
// asked, and bad options give one line naming the option and a non-zero exit.

#include <utility>  // before Asio: Boost 1.74's awaitable.hpp uses std::exchange without it

#include <boost/asio.hpp>
#include <boost/beast/core.hpp>
#include <boost/beast/websocket.hpp>

#include <chrono>
#include <cstring>
#include <fstream>
#include <nlohmann/json.hpp>
#include <regex>
#include <sstream>
#include <thread>

#include "cli/cli_test_util.h"

namespace zipfusion {
namespace {

using testing::CliTest;
using testing::CommandResult;
using testing::line_count;

class ServeCli : public CliTest {};

// serve's summary: frame sets made, dropped to keep up, and not made as no viewer was ready.
const std::regex kServedLine("served (\\d+) frame sets \\((\\d+) dropped by the pipeline to keep up, (\\d+) not made");

// What a serve started in the background has printed so far.
std::string read_text(const std::filesystem::path& path) {
  std::ifstream in(path);
  std::stringstream s;
  s << in.rdbuf();
  return s.str();
}

// The port of a serve started in the background once it prints where it serves (0 after 10 s
// without), and what it printed by then.
std::pair<int, std::string> wait_for_serving(const std::filesystem::path& out) {
  std::smatch url;
  std::string text;
  for (int i = 0; i < 200 && !std::regex_search(text, url, std::regex("serving http://127\\.0\\.0\\.1:(\\d+)/")); ++i) {
    std::this_thread::sleep_for(std::chrono::milliseconds(50));
    text = read_text(out);
  }
  return {url.empty() ? 0 : std::stoi(url[1]), text};
}

// A viewer's WebSocket to serve's stream on this machine.
void connect_viewer(boost::beast::websocket::stream<boost::asio::ip::tcp::socket>& ws, int port) {
  ws.next_layer().connect({boost::asio::ip::make_address("127.0.0.1"), static_cast<unsigned short>(port)});
  ws.handshake("127.0.0.1", "/stream");
}

TEST_F(ServeCli, StreamsAtTheCaptureFrameRateForTheTimeAsked) {
  const std::string capture = (dir_ / "cap").string();
  ASSERT_EQ(run("synth --out " + capture + " --frames 6 --cameras 2").exit_code, 0);
  const CommandResult r = run("serve " + capture + " --loop --seconds 2 --port 0");
  ASSERT_EQ(r.exit_code, 0) << r.err;
  EXPECT_NE(r.out.find("serving http://127.0.0.1:"), std::string::npos) << r.out;
  std::smatch served;
  ASSERT_TRUE(std::regex_search(r.out, served, kServedLine)) << r.out;
  // 2 s at 30 fps, looping over 6 frames: 60 frame sets handed over, and with no viewer none is
  // made (the pipeline may also drop one, as live, on a busy machine).
  EXPECT_EQ(std::stoi(served[1]) + std::stoi(served[2]) + std::stoi(served[3]), 60) << r.out;
  EXPECT_EQ(std::stoi(served[1]), 0) << r.out;
  EXPECT_GE(std::stoi(served[3]), 30) << r.out;
  // Without --loop the stream ends with the capture.
  const CommandResult once = run("serve " + capture + " --port 0");
  ASSERT_EQ(once.exit_code, 0) << once.err;
  ASSERT_TRUE(std::regex_search(once.out, served, kServedLine)) << once.out;
  EXPECT_EQ(std::stoi(served[1]) + std::stoi(served[2]) + std::stoi(served[3]), 6) << once.out;
  // Bound to every interface, the URL names this machine, which others can open (not 0.0.0.0).
  const CommandResult everywhere = run("serve " + capture + " --bind 0.0.0.0 --port 0 --frames 0:1");
  ASSERT_EQ(everywhere.exit_code, 0) << everywhere.err;
  char host[256] = {};
  ASSERT_EQ(::gethostname(host, sizeof host - 1), 0);
  EXPECT_NE(everywhere.out.find("serving http://" + std::string(host) + ":"), std::string::npos) << everywhere.out;
}

// A viewer slower than the stream (it acknowledges each frame 150 ms after it arrives, with one
// frame in flight) gets frames made for it: in order, with the frame sets made while it was busy
// skipped unmade, as the summary counts.
TEST_F(ServeCli, MakesFramesOnlyWhenTheViewerHasRoom) {
  namespace net = boost::asio;
  namespace websocket = boost::beast::websocket;
  const std::string capture = (dir_ / "cap").string();
  ASSERT_EQ(run("synth --out " + capture + " --frames 6 --cameras 2").exit_code, 0);
  const auto out = dir_ / "serve.out";
  // 15 s: the server must outlast the viewer's 8 slow frames also where ThreadSanitizer slows it
  // (with 5 s it ended first once, and the viewer's read met the end of the stream).
  constexpr int kServeSeconds = 15;
  const std::string command = std::string(ZF_BINARY) + " serve " + capture + " --loop --seconds " + std::to_string(kServeSeconds) +
                              " --port 0 > " + out.string() + " 2>&1 < /dev/null &";
  ASSERT_EQ(std::system(command.c_str()), 0);
  auto [port, text] = wait_for_serving(out);
  ASSERT_NE(port, 0) << text;
  net::io_context io;
  websocket::stream<net::ip::tcp::socket> ws(io);
  connect_viewer(ws, port);
  auto send = [&](const std::string& command_text) {
    ws.text(true);
    ws.write(net::buffer(command_text));
  };
  // Until the window is set the client takes every frame, as one without flow control would; the
  // server has set it once it answers the ping sent after it. Each of those frames is acknowledged
  // as the viewer does: one queued before the window was set but sent after counts against it,
  // and left unacknowledged it would hold the window shut (a stall seen beside other tests).
  send(R"({"type":"flow","window":1})");
  send(R"({"type":"ping","t":1})");
  int before_window = 0;
  while (true) {
    boost::beast::flat_buffer buffer;
    ws.read(buffer);
    if (ws.got_binary()) {
      ++before_window;
      send(R"({"type":"ack"})");
    } else if (boost::beast::buffers_to_string(buffer.data()).find("pong") != std::string::npos) {
      break;
    }
  }
  std::vector<long> sequences;
  while (sequences.size() < 8) {
    boost::beast::flat_buffer buffer;
    ws.read(buffer);
    if (!ws.got_binary()) continue;
    const std::string message = boost::beast::buffers_to_string(buffer.data());
    ASSERT_EQ(message.compare(0, 4, "ZFM1"), 0);
    std::uint32_t length = 0;
    std::memcpy(&length, message.data() + 4, 4);
    sequences.push_back(nlohmann::json::parse(message.substr(8, length)).at("sequence").get<long>());
    std::this_thread::sleep_for(std::chrono::milliseconds(150));  // drawing, slowly
    send(R"({"type":"ack"})");
  }
  ws.next_layer().close();
  long largest_step = 0;
  for (size_t i = 1; i < sequences.size(); ++i) {
    EXPECT_GT(sequences[i], sequences[i - 1]);
    largest_step = std::max(largest_step, sequences[i] - sequences[i - 1]);
  }
  EXPECT_GE(largest_step, 2) << "the header's sequence must count the frame sets not made";
  for (int i = 0; i < 20 * (kServeSeconds + 10) && text.find("served ") == std::string::npos; ++i) {
    std::this_thread::sleep_for(std::chrono::milliseconds(50));
    text = read_text(out);
  }
  std::smatch served;
  ASSERT_TRUE(std::regex_search(text, served, kServedLine)) << text;
  // One frame made per acknowledgement, one more after the last, and those made before the
  // window was set: not the 450 frame sets of fifteen seconds. The others were not made; a machine
  // too busy to read them at 30 fps (ThreadSanitizer's slowdown: 46 of 150) drops some first.
  EXPECT_GE(std::stoi(served[1]), 8) << text;
  EXPECT_LE(std::stoi(served[1]), before_window + 8 + 2) << text;
  EXPECT_GT(std::stoi(served[2]) + std::stoi(served[3]), kServeSeconds * 30 * 2 / 3) << text;
}

// Ctrl-C stops serve at once, also while it waits 20 s for a slow capture's next frame; the
// capture named with a trailing slash keeps its name in the viewer's hello.
TEST_F(ServeCli, CtrlCStopsAtOnceBetweenSlowFrames) {
  namespace net = boost::asio;
  namespace websocket = boost::beast::websocket;
  const std::string capture = (dir_ / "slow").string();
  ASSERT_EQ(run("synth --out " + capture + " --frames 2 --cameras 2 --fps 0.05 --resolution 64x48").exit_code, 0);
  const auto out = dir_ / "serve.out", pid_file = dir_ / "serve.pid";
  // A background job of sh, which ignores SIGINT for it: serve catches it all the same.
  const std::string command = std::string(ZF_BINARY) + " serve " + capture + "/ --loop --port 0 --threads 1 > " + out.string() +
                              " 2>&1 < /dev/null & echo $! > " + pid_file.string();
  ASSERT_EQ(std::system(command.c_str()), 0);
  // However the test ends, the server it started does not outlive it (--loop never ends alone).
  struct KillOnExit {
    std::filesystem::path pid_file;
    ~KillOnExit() {
      if (std::system(("kill -9 $(cat " + pid_file.string() + ") 2> /dev/null").c_str()) != 0) return;  // already gone: stopped as asked
    }
  } kill_on_exit{pid_file};
  auto [port, text] = wait_for_serving(out);
  ASSERT_NE(port, 0) << text;
  {
    net::io_context io;
    websocket::stream<net::ip::tcp::socket> ws(io);
    connect_viewer(ws, port);
    boost::beast::flat_buffer buffer;
    ws.read(buffer);
    const nlohmann::json hello = nlohmann::json::parse(boost::beast::buffers_to_string(buffer.data()));
    EXPECT_EQ(hello.at("capture"), "slow") << hello;
    ws.next_layer().close();
  }
  std::this_thread::sleep_for(std::chrono::milliseconds(500));  // into the 20 s wait for frame 1
  ASSERT_EQ(std::system(("kill -INT $(cat " + pid_file.string() + ")").c_str()), 0);
  // Waiting for frame 1, 19 s on, it would not print its summary within these 5 s.
  for (int i = 0; i < 200 && text.find("served ") == std::string::npos; ++i) {
    std::this_thread::sleep_for(std::chrono::milliseconds(25));
    text = read_text(out);
  }
  std::smatch served;
  ASSERT_TRUE(std::regex_search(text, served, kServedLine)) << text;
  // Only frame 0 was taken from the capture (served, dropped or not made): frame 1 never came due.
  EXPECT_EQ(std::stoi(served[1]) + std::stoi(served[2]) + std::stoi(served[3]), 1) << text;
}

// serve --live streams live cameras: here a fakenect dump replayed as a camera, at its recorded
// pace (as the device delivered it), once or looped for the time asked.
TEST_F(ServeCli, StreamsLiveCameras) {
  const std::string dump = (dir_ / "dump").string();
  ASSERT_EQ(run("synth --fakenect " + dump + " --frames 8").exit_code, 0);
  const auto started = std::chrono::steady_clock::now();
  CommandResult r = run("serve --live --replay " + dump + " --port 0");
  ASSERT_EQ(r.exit_code, 0) << r.err;
  // Eight frames 1/30 s apart are not over before the last one's time.
  EXPECT_GE(std::chrono::steady_clock::now() - started, std::chrono::milliseconds(7 * 1000 / 30));
  std::smatch served;
  ASSERT_TRUE(std::regex_search(r.out, served, kServedLine)) << r.out;
  EXPECT_EQ(std::stoi(served[1]) + std::stoi(served[2]) + std::stoi(served[3]), 8) << r.out;
  // Looped for 2 s: the 8 frames again and again at 30 fps, as a capture with --loop.
  r = run("serve --live --replay " + dump + " --loop --seconds 2 --port 0");
  ASSERT_EQ(r.exit_code, 0) << r.err;
  EXPECT_NE(r.out.find("looping"), std::string::npos) << r.out;
  ASSERT_TRUE(std::regex_search(r.out, served, kServedLine)) << r.out;
  const int handed_over = std::stoi(served[1]) + std::stoi(served[2]) + std::stoi(served[3]);
  EXPECT_GE(handed_over, 50) << r.out;
  EXPECT_LE(handed_over, 61) << r.out;
  // Devices are not a recording: nothing to loop.
  r = run("serve --live --devices all --loop --port 0");
  EXPECT_EQ(r.exit_code, 2);
  EXPECT_EQ(r.err, "zipfusion: error: --loop: only for a capture or --replay\n");
}

TEST_F(ServeCli, BadOptionsGiveOneLineAndNonZeroExit) {
  const std::string capture = (dir_ / "cap").string();
  ASSERT_EQ(run("synth --out " + capture + " --frames 2 --cameras 2").exit_code, 0);
  struct Case {
    std::string args, expected;
  };
  const std::vector<Case> cases = {
      {"serve " + capture + " --port 70000", "--port"},
      {"serve " + capture + " --bind not-an-address --port 0", "--bind"},
      {"serve " + capture + " --token 'a b' --port 0", "--token"},
      {"serve " + capture + " --web " + (dir_ / "nowhere").string() + " --port 0", "index.html"},
      {"serve " + capture + " --lod 9 --port 0", "--lod: must be in [0, 3]"},
      {"serve " + capture + " --position-bits 0 --port 0", "--position-bits: must be in [1, 30]"},
      {"serve " + capture + " --token '' --port 0", "--token: must not be empty"},
      {"serve " + (dir_ / "missing").string() + " --port 0", "missing"},
      // Checked before the port is bound and the address printed (serve binds before refining).
      {"serve " + capture + " --coarse-shrink 7 --port 0", "--coarse-shrink: must be in (0, 1]"},
  };
  for (const Case& c : cases) {
    const CommandResult r = run(c.args);
    EXPECT_NE(r.exit_code, 0) << c.args;
    EXPECT_EQ(r.out, "") << c.args;
    EXPECT_EQ(line_count(r.err), 1) << c.args << "\n" << r.err;
    EXPECT_NE(r.err.find(c.expected), std::string::npos) << c.args << "\n" << r.err;
  }
}

}  // namespace
}  // namespace zipfusion
