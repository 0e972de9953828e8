// Many viewers of a running `zipfusion serve` at once, one of them stalled (it connects and then
// never reads): per reading client the frames received per second, and over all of them the
// latency from capture to arrival (the header's capture_time_ms against this machine's clock, so
// on loopback) and the frame size. Issue 8's targets: every reader at the stream's full rate
// while one client stalls. With --window N the readers ask for flow control with N frames in
// flight and acknowledge each frame as it arrives, as a viewer with a GPU would soon after.
// Usage:
//   zf_stream_clients --port P [--clients 20] [--stalled 1] [--window 0] [--seconds 10] [--json]

#include <utility>  // before Asio: Boost 1.74's awaitable.hpp uses std::exchange without it

#include <boost/asio.hpp>
#include <boost/beast/core.hpp>
#include <boost/beast/websocket.hpp>

#include <algorithm>
#include <atomic>
#include <chrono>
#include <cstdio>
#include <cstring>
#include <mutex>
#include <nlohmann/json.hpp>
#include <string>
#include <thread>
#include <vector>

namespace {

namespace net = boost::asio;
namespace beast = boost::beast;
namespace websocket = beast::websocket;
using tcp = net::ip::tcp;

double epoch_ms() {
  return std::chrono::duration<double, std::milli>(std::chrono::system_clock::now().time_since_epoch()).count();
}

double percentile(std::vector<double> v, double q) {
  if (v.empty()) return 0;
  std::sort(v.begin(), v.end());
  return v[std::min(v.size() - 1, static_cast<size_t>(q * static_cast<double>(v.size())))];
}

struct Reader {
  int frames = 0;
  std::vector<double> latency_ms, bytes;
  double first_ms = 0, last_ms = 0;
};

}  // namespace

int main(int argc, char** argv) {
  int port = 8080, clients = 20, stalled = 1, window = 0;
  double seconds = 10;
  bool json = false;
  std::string token;
  for (int i = 1; i < argc; ++i) {
    const std::string a = argv[i];
    auto value = [&] { return i + 1 < argc ? std::string(argv[++i]) : std::string(); };
    if (a == "--port") port = std::stoi(value());
    else if (a == "--clients") clients = std::stoi(value());
    else if (a == "--stalled") stalled = std::stoi(value());
    else if (a == "--seconds") seconds = std::stod(value());
    else if (a == "--window") window = std::stoi(value());
    else if (a == "--token") token = value();
    else if (a == "--json") json = true;
    else {
      std::fprintf(stderr, "zf_stream_clients: unknown option %s\n", a.c_str());
      return 2;
    }
  }
  const std::string target = token.empty() ? "/stream" : "/stream?token=" + token;
  std::vector<Reader> readers(clients - stalled);
  std::vector<std::unique_ptr<net::io_context>> ios;
  std::vector<std::unique_ptr<websocket::stream<tcp::socket>>> sockets;
  try {
    for (int c = 0; c < clients; ++c) {
      ios.push_back(std::make_unique<net::io_context>());
      sockets.push_back(std::make_unique<websocket::stream<tcp::socket>>(*ios.back()));
      sockets.back()->next_layer().connect({net::ip::make_address("127.0.0.1"), static_cast<unsigned short>(port)});
      sockets.back()->handshake("127.0.0.1", target);
    }
  } catch (const std::exception& e) {
    std::fprintf(stderr, "zf_stream_clients: cannot connect to 127.0.0.1:%d: %s\n", port, e.what());
    return 3;
  }
  const auto end = std::chrono::steady_clock::now() + std::chrono::duration_cast<std::chrono::steady_clock::duration>(std::chrono::duration<double>(seconds));
  std::vector<std::thread> threads;
  for (int c = 0; c < clients - stalled; ++c) {
    threads.emplace_back([&, c] {
      Reader& r = readers[c];
      websocket::stream<tcp::socket>& ws = *sockets[c];
      auto send = [&ws](const std::string& command) {
        ws.text(true);
        ws.write(net::buffer(command));
      };
      try {
        if (window > 0) send(R"({"type":"flow","window":)" + std::to_string(window) + "}");
        while (std::chrono::steady_clock::now() < end) {
          beast::flat_buffer buffer;
          ws.read(buffer);
          const double now = epoch_ms();
          if (!ws.got_binary()) continue;
          const std::string message = beast::buffers_to_string(buffer.data());
          if (message.size() < 8 || message.compare(0, 4, "ZFM1") != 0) continue;
          std::uint32_t length = 0;
          std::memcpy(&length, message.data() + 4, 4);
          if (window > 0) send(R"({"type":"ack"})");
          const nlohmann::json header = nlohmann::json::parse(message.substr(8, length));
          if (r.frames == 0) r.first_ms = now;
          r.last_ms = now;
          ++r.frames;
          r.latency_ms.push_back(now - header.value("capture_time_ms", now));
          r.bytes.push_back(static_cast<double>(message.size()));
        }
      } catch (const std::exception&) {
      }
    });
  }
  for (auto& t : threads) t.join();
  for (auto& s : sockets) {
    beast::error_code ignored;
    s->next_layer().close(ignored);
  }
  std::vector<double> rates, latencies, sizes;
  for (const Reader& r : readers) {
    rates.push_back(r.frames > 1 ? (r.frames - 1) * 1000.0 / (r.last_ms - r.first_ms) : 0);
    latencies.insert(latencies.end(), r.latency_ms.begin(), r.latency_ms.end());
    sizes.insert(sizes.end(), r.bytes.begin(), r.bytes.end());
  }
  const double min_rate = rates.empty() ? 0 : *std::min_element(rates.begin(), rates.end());
  const double max_rate = rates.empty() ? 0 : *std::max_element(rates.begin(), rates.end());
  double mean_size = 0;
  for (double s : sizes) mean_size += s / static_cast<double>(std::max<size_t>(1, sizes.size()));
  if (json) {
    std::printf("%s\n", nlohmann::json({{"clients", clients},
                                        {"stalled", stalled},
                                        {"window", window},
                                        {"seconds", seconds},
                                        {"reader_fps_min", min_rate},
                                        {"reader_fps_max", max_rate},
                                        {"latency_ms_median", percentile(latencies, 0.5)},
                                        {"latency_ms_p95", percentile(latencies, 0.95)},
                                        {"frame_kb_mean", mean_size / 1024}})
                            .dump()
                            .c_str());
  } else {
    std::printf("%d clients (%d stalled) for %.0f s: readers at %.1f to %.1f frames/s; capture-to-arrival latency median %.1f ms, p95 %.1f ms; "
                "%.1f kB per frame\n",
                clients, stalled, seconds, min_rate, max_rate, percentile(latencies, 0.5), percentile(latencies, 0.95), mean_size / 1024);
  }
  return 0;
}
