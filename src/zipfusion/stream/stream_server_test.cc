#include "zipfusion/stream/stream_server.h"

#include <gtest/gtest.h>
#include <sys/socket.h>

#include <utility>  // before Asio: Boost 1.74's awaitable.hpp uses std::exchange without it

#include <boost/asio.hpp>
#include <boost/beast/core.hpp>
#include <boost/beast/http.hpp>
#include <boost/beast/websocket.hpp>

#include <atomic>
#include <chrono>
#include <fstream>
#include <memory>
#include <thread>

#include "zipfusion/core/error.h"

namespace zipfusion {
namespace {

namespace net = boost::asio;
namespace beast = boost::beast;
namespace http = beast::http;
namespace websocket = beast::websocket;
using tcp = net::ip::tcp;
namespace fs = std::filesystem;

struct HttpReply {
  int status = 0;
  std::string body, cookie;
};

HttpReply http_get(int port, const std::string& target, const std::string& cookie = "") {
  net::io_context io;
  tcp::socket socket(io);
  socket.connect({net::ip::make_address("127.0.0.1"), static_cast<unsigned short>(port)});
  http::request<http::empty_body> request(http::verb::get, target, 11);
  request.set(http::field::host, "127.0.0.1");
  if (!cookie.empty()) request.set(http::field::cookie, cookie);
  http::write(socket, request);
  beast::flat_buffer buffer;
  http::response<http::string_body> response;
  http::read(socket, buffer, response);
  return {static_cast<int>(response.result_int()), response.body(), std::string(response[http::field::set_cookie])};
}

// The status line of the reply to a request written by hand.
std::string raw_request(int port, const std::string& request) {
  net::io_context io;
  tcp::socket socket(io);
  socket.connect({net::ip::make_address("127.0.0.1"), static_cast<unsigned short>(port)});
  net::write(socket, net::buffer(request));
  std::string reply(64, '\0');
  beast::error_code ec;
  const size_t n = socket.read_some(net::buffer(reply), ec);
  reply.resize(n);
  return reply.substr(0, reply.find("\r\n"));
}

// A WebSocket client of the stream on its own connection (blocking calls).
struct Client {
  net::io_context io;
  websocket::stream<tcp::socket> ws{io};

  explicit Client(int port, const std::string& target = "/stream", const std::string& cookie = "") {
    ws.next_layer().connect({net::ip::make_address("127.0.0.1"), static_cast<unsigned short>(port)});
    ws.set_option(websocket::stream_base::decorator([cookie](websocket::request_type& request) {
      if (!cookie.empty()) request.set(http::field::cookie, cookie);
    }));
    ws.handshake("127.0.0.1", target);
  }

  std::string read(bool* binary = nullptr) {
    beast::flat_buffer buffer;
    ws.read(buffer);
    if (binary != nullptr) *binary = ws.got_binary();
    return beast::buffers_to_string(buffer.data());
  }

  void send(const std::string& command) {
    ws.text(true);
    ws.write(net::buffer(command));
  }
};

// A client of `server` that has read the stream's description and set a flow window: the server
// has handled the window once it answers the ping sent after it (commands are handled in order).
std::unique_ptr<Client> client_with_window(const StreamServer& server, int window) {
  auto client = std::make_unique<Client>(server.port());
  EXPECT_EQ(client->read(), "{}");
  client->send(R"({"type":"flow","window":)" + std::to_string(window) + "}");
  client->send(R"({"type":"ping","t":1})");
  EXPECT_EQ(client->read(), R"({"t":1,"type":"pong"})");
  return client;
}

class StreamServerTest : public ::testing::Test {
 protected:
  void SetUp() override {
    dir_ = fs::temp_directory_path() / ("zf_stream_test_" + std::to_string(::getpid()));
    fs::create_directories(dir_ / "draco");
    std::ofstream(dir_ / "index.html") << "<!doctype html><title>viewer</title>";
    std::ofstream(dir_ / "draco" / "decoder.js") << "// decoder";
  }
  void TearDown() override { fs::remove_all(dir_); }
  fs::path dir_;
};

TEST(StreamServerUrl, IPv6HostsGoInBracketsWithTheirZoneEscaped) {
  EXPECT_EQ(url_host("127.0.0.1"), "127.0.0.1");
  EXPECT_EQ(url_host("localhost"), "localhost");
  EXPECT_EQ(url_host("::1"), "[::1]");
  EXPECT_EQ(url_host("fe80::1%eth0"), "[fe80::1%25eth0]");
}

// At most 64 viewers, also when their upgrades arrive together: handshakes under way count.
TEST_F(StreamServerTest, UpgradesArrivingTogetherStayWithinTheClientLimit) {
  StreamServer server({.port = 0}, "{}");
  net::io_context io;
  std::vector<std::unique_ptr<tcp::socket>> sockets;
  const std::string upgrade =
      "GET /stream HTTP/1.1\r\nHost: 127.0.0.1\r\nUpgrade: websocket\r\nConnection: Upgrade\r\n"
      "Sec-WebSocket-Key: dGhlIHNhbXBsZSBub25jZQ==\r\nSec-WebSocket-Version: 13\r\n\r\n";
  for (int i = 0; i < 150; ++i) {
    sockets.push_back(std::make_unique<tcp::socket>(io));
    sockets.back()->connect({net::ip::make_address("127.0.0.1"), static_cast<unsigned short>(server.port())});
  }
  for (auto& socket : sockets) net::write(*socket, net::buffer(upgrade));
  int switched = 0, refused = 0;
  for (auto& socket : sockets) {
    std::string reply(64, '\0');
    beast::error_code ec;
    reply.resize(socket->read_some(net::buffer(reply), ec));
    if (reply.starts_with("HTTP/1.1 101")) ++switched;
    if (reply.starts_with("HTTP/1.1 503")) ++refused;
  }
  EXPECT_EQ(switched, 64);
  EXPECT_EQ(refused, 150 - 64);
}

TEST_F(StreamServerTest, ServesTheViewerAndTheStream) {
  StreamServer server({.port = 0, .web_root = dir_}, R"({"format":"zipfusion.stream/1"})");
  ASSERT_GT(server.port(), 0);
  const HttpReply page = http_get(server.port(), "/");
  EXPECT_EQ(page.status, 200);
  EXPECT_NE(page.body.find("<title>viewer</title>"), std::string::npos);
  EXPECT_EQ(http_get(server.port(), "/draco/decoder.js").status, 200);
  for (const char* bad : {"/../etc/passwd", "/draco/../../x", "/.hidden", "/a/b/c.js", "/missing.js", "/draco"}) {
    EXPECT_EQ(http_get(server.port(), bad).status, 404) << bad;
  }
  // The stream asked for as a page: it says what it is.
  const HttpReply plain = http_get(server.port(), "/stream");
  EXPECT_EQ(plain.status, 426);
  EXPECT_EQ(plain.body, "the stream is a WebSocket: open / for the viewer\n");
  // A target without its leading slash, another site's page, a name rebound to this machine:
  // refused, and the server goes on.
  EXPECT_EQ(raw_request(server.port(), "GET ?x HTTP/1.1\r\nHost: 127.0.0.1\r\n\r\n"), "HTTP/1.1 400 Bad Request");
  EXPECT_EQ(raw_request(server.port(), "GET / HTTP/1.1\r\nHost: 127.0.0.1\r\nOrigin: http://evil.example\r\n\r\n"), "HTTP/1.1 403 Forbidden");
  EXPECT_EQ(raw_request(server.port(), "GET / HTTP/1.1\r\nHost: rebound.example:8080\r\n\r\n"), "HTTP/1.1 403 Forbidden");
  // A DNS name that merely starts like a loopback address is a name, not the loopback.
  EXPECT_EQ(raw_request(server.port(), "GET / HTTP/1.1\r\nHost: 127.attacker.example:8080\r\n\r\n"), "HTTP/1.1 403 Forbidden");
  EXPECT_EQ(raw_request(server.port(), "GET / HTTP/1.1\r\nHost: 127.1.2.3\r\n\r\n"), "HTTP/1.1 200 OK");
  // Without a Host (HTTP/1.1 requires one, HTTP/1.0 does not), not HTTP, too large: a status
  // that says so, not a silent close.
  EXPECT_EQ(raw_request(server.port(), "GET / HTTP/1.0\r\n\r\n"), "HTTP/1.0 200 OK");
  EXPECT_EQ(raw_request(server.port(), "GET / HTTP/1.1\r\n\r\n"), "HTTP/1.1 400 Bad Request");
  EXPECT_EQ(raw_request(server.port(), std::string("\x00\x01garbage\r\n\r\n", 13)), "HTTP/1.1 400 Bad Request");
  EXPECT_EQ(raw_request(server.port(), "GET / HTTP/1.1\r\nHost: 127.0.0.1\r\nX-Big: " + std::string(9000, 'a') + "\r\n\r\n"),
            "HTTP/1.1 431 Request Header Fields Too Large");
  EXPECT_EQ(raw_request(server.port(), "POST / HTTP/1.1\r\nHost: 127.0.0.1\r\nContent-Length: 9000\r\n\r\n" + std::string(9000, 'a')),
            "HTTP/1.1 413 Payload Too Large");
  EXPECT_EQ(raw_request(server.port(), "GET / HTTP/1.1\r\nHost: [::1]:8080\r\n\r\n"), "HTTP/1.1 200 OK");
  EXPECT_EQ(http_get(server.port(), "/").status, 200);
  Client client(server.port());
  bool binary = true;
  EXPECT_EQ(client.read(&binary), R"({"format":"zipfusion.stream/1"})");
  EXPECT_FALSE(binary);
  while (server.stats().clients < 1) std::this_thread::sleep_for(std::chrono::milliseconds(1));
  const std::string message = frame_message(R"({"frame":7})", std::string("\x01\x02\x03", 3));
  server.broadcast(message);
  EXPECT_EQ(client.read(&binary), message);
  EXPECT_TRUE(binary);
  ASSERT_EQ(message.substr(0, 4), "ZFM1");
  EXPECT_EQ(static_cast<unsigned char>(message[4]), 11u);  // the header's length, little-endian
  EXPECT_EQ(message.substr(8, 11), R"({"frame":7})");
  // A ping is answered with its own time.
  client.ws.text(true);
  client.ws.write(net::buffer(std::string(R"({"type":"ping","t":12.5})")));
  EXPECT_EQ(client.read(), R"({"t":12.5,"type":"pong"})");
}

TEST_F(StreamServerTest, WithATokenOnlyItsHoldersAreServed) {
  StreamServer server({.port = 0, .token = "s3cret", .web_root = dir_}, "{}");
  EXPECT_EQ(http_get(server.port(), "/").status, 401);
  EXPECT_EQ(http_get(server.port(), "/?token=wrong").status, 401);
  EXPECT_THROW(Client(server.port()), boost::system::system_error);
  EXPECT_THROW(Client(server.port(), "/stream?token=s3cre"), boost::system::system_error);
  const HttpReply page = http_get(server.port(), "/?token=s3cret");
  EXPECT_EQ(page.status, 200);
  ASSERT_NE(page.cookie.find("zf_token=s3cret"), std::string::npos);
  // The page's cookie admits its scripts and its stream.
  EXPECT_EQ(http_get(server.port(), "/draco/decoder.js", "zf_token=s3cret").status, 200);
  Client with_cookie(server.port(), "/stream", "zf_token=s3cret");
  EXPECT_EQ(with_cookie.read(), "{}");
  Client with_query(server.port(), "/stream?token=s3cret");
  EXPECT_EQ(with_query.read(), "{}");
  EXPECT_GE(server.stats().refused, 4);
  EXPECT_THROW(StreamServer({.port = 0, .token = "a b"}, "{}"), InvalidInput);
}

// A hello replaced after the server started (`serve` refines the poses after binding its port)
// goes to the clients connected and to those that come after.
TEST_F(StreamServerTest, AReplacedHelloReachesEveryClient) {
  StreamServer server({.port = 0}, R"({"poses":"given"})");
  Client before(server.port());
  EXPECT_EQ(before.read(), R"({"poses":"given"})");
  server.set_hello(R"({"poses":"refined"})");
  EXPECT_EQ(before.read(), R"({"poses":"refined"})");
  Client after(server.port());
  EXPECT_EQ(after.read(), R"({"poses":"refined"})");
}

// With a flow window of one, a viewer gets a frame only after acknowledging the previous one, and
// then the newest: no backlog builds up in the network for a viewer slower than the stream.
TEST_F(StreamServerTest, FlowControlSendsTheNewestFrameAfterEachAck) {
  StreamServer server({.port = 0}, "{}");
  const std::unique_ptr<Client> connection = client_with_window(server, 1);
  Client& client = *connection;
  for (int k = 0; k < 5; ++k) server.broadcast(frame_message("{\"frame\":" + std::to_string(k) + "}", ""));
  EXPECT_EQ(client.read(), frame_message("{\"frame\":0}", ""));
  // Frames 1 to 3 are skipped while frame 0 is unacknowledged; the newest, 4, waits.
  while (server.stats().frames_skipped < 3) std::this_thread::sleep_for(std::chrono::milliseconds(1));
  client.ws.write(net::buffer(std::string(R"({"type":"ack"})")));
  EXPECT_EQ(client.read(), frame_message("{\"frame\":4}", ""));
  EXPECT_EQ(server.stats().frames_skipped, 3);
  // A bad window closes the client, like any malformed command.
  client.ws.write(net::buffer(std::string(R"({"type":"flow","window":100})")));
  EXPECT_THROW(client.read(), boost::system::system_error);
}

// A window past int's range is refused, not narrowed: 2^32 + 1 read as an int would be a window of
// one. The ping after it would be answered if the window had been taken.
TEST_F(StreamServerTest, AWindowPastIntsRangeClosesTheClient) {
  StreamServer server({.port = 0}, "{}");
  for (const char* window : {"4294967297", "18446744073709551615", "-4294967295"}) {
    const std::unique_ptr<Client> connection = client_with_window(server, 1);
    Client& client = *connection;
    client.ws.write(net::buffer(std::string(R"({"type":"flow","window":)") + window + "}"));
    client.ws.write(net::buffer(std::string(R"({"type":"ping"})")));
    EXPECT_THROW(client.read(), boost::system::system_error) << window;
  }
}

// A stream makes a frame only when some client can be sent it at once (StreamServer::
// reserve_frame): nobody watching, nothing made; a viewer with a window of one, one frame per ack.
TEST_F(StreamServerTest, FramesAreReservedOnlyForClientsWithRoom) {
  StreamServer server({.port = 0}, "{}");
  EXPECT_FALSE(server.reserve_frame());  // no client
  const std::unique_ptr<Client> connection = client_with_window(server, 1);
  Client& client = *connection;
  EXPECT_TRUE(server.reserve_frame());
  EXPECT_FALSE(server.reserve_frame());  // the one place is taken by the frame being made
  server.broadcast(frame_message("{\"frame\":0}", ""));
  EXPECT_EQ(client.read(), frame_message("{\"frame\":0}", ""));
  EXPECT_FALSE(server.reserve_frame());  // frame 0 is unacknowledged
  client.send(R"({"type":"ack"})");
  client.send(R"({"type":"ping","t":3})");
  EXPECT_EQ(client.read(), R"({"t":3,"type":"pong"})");
  EXPECT_TRUE(server.reserve_frame());
  // Paused, it wants nothing; a client without flow control takes every frame.
  server.broadcast(frame_message("{\"frame\":1}", ""));
  EXPECT_EQ(client.read(), frame_message("{\"frame\":1}", ""));
  client.send(R"({"type":"ack"})");
  client.send(R"({"type":"pause"})");
  client.send(R"({"type":"ping","t":4})");
  EXPECT_EQ(client.read(), R"({"t":4,"type":"pong"})");
  EXPECT_FALSE(server.reserve_frame());
  Client unlimited(server.port());
  EXPECT_EQ(unlimited.read(), "{}");
  EXPECT_TRUE(server.reserve_frame());  // its room was counted before its first message was sent
  for (int k = 0; k < 10; ++k) EXPECT_TRUE(server.reserve_frame());
}

// A window that grows sends the held frame at once, so a frame broadcast later never arrives before
// it (the viewer changes its window while it plays).
TEST_F(StreamServerTest, AGrowingWindowKeepsFramesInOrder) {
  StreamServer server({.port = 0}, "{}");
  const std::unique_ptr<Client> connection = client_with_window(server, 1);
  Client& client = *connection;
  server.broadcast(frame_message("{\"frame\":0}", ""));
  server.broadcast(frame_message("{\"frame\":1}", ""));  // held: frame 0 is unacknowledged
  EXPECT_EQ(client.read(), frame_message("{\"frame\":0}", ""));
  client.send(R"({"type":"flow","window":2})");
  client.send(R"({"type":"ping","t":2})");
  EXPECT_EQ(client.read(), frame_message("{\"frame\":1}", ""));  // released by the larger window, before the reply
  EXPECT_EQ(client.read(), R"({"t":2,"type":"pong"})");
  server.broadcast(frame_message("{\"frame\":2}", ""));  // held again: two unacknowledged
  client.ws.write(net::buffer(std::string(R"({"type":"ack"})")));
  EXPECT_EQ(client.read(), frame_message("{\"frame\":2}", ""));
  EXPECT_EQ(server.stats().frames_skipped, 0);
}

TEST_F(StreamServerTest, BadMessagesCloseOnlyTheirClient) {
  StreamServer server({.port = 0}, "{}");
  Client good(server.port()), garbage(server.port()), oversized(server.port());
  for (Client* c : {&good, &garbage, &oversized}) EXPECT_EQ(c->read(), "{}");
  garbage.ws.text(true);
  garbage.ws.write(net::buffer(std::string("this is not json")));
  oversized.ws.text(true);
  oversized.ws.write(net::buffer(std::string(4096, ' ')));
  for (auto [c, code] : {std::pair(&garbage, websocket::close_code::policy_error), std::pair(&oversized, websocket::close_code::too_big)}) {
    try {
      c->read();
      ADD_FAILURE() << "a bad client was not closed";
    } catch (const boost::system::system_error& e) {
      // A closing handshake with the reason; only for the oversized message may the server drop
      // the connection instead, while the message is still arriving.
      if (c == &garbage || e.code() == websocket::error::closed) {
        EXPECT_EQ(e.code(), websocket::error::closed) << e.code().message();
        EXPECT_EQ(c->ws.reason().code, code);
      }
    }
  }
  while (server.stats().clients > 1) std::this_thread::sleep_for(std::chrono::milliseconds(1));
  server.broadcast(frame_message("{}", "x"));
  bool binary = false;
  EXPECT_EQ(good.read(&binary).size(), 4u + 4u + 2u + 1u);
  EXPECT_TRUE(binary);
  EXPECT_EQ(server.stats().closed_bad_message, 2);
}

// Twenty viewers, one of which never reads: the nineteen others get every frame, the stalled one
// skips, and broadcasting never waits for it. Each client may have 8 frames waiting (the default
// is 2): with 2, a stall of the machine longer than two frame periods (33 ms: `make test` runs
// heavy tests side by side on two cores) skipped one frame of every reader, which is the queue
// doing its job, not the stalled client slowing the others.
TEST_F(StreamServerTest, AStalledClientSlowsNobody) {
  StreamServer server({.port = 0, .client_queue_frames = 8}, "{}");
  constexpr int kReaders = 19, kFrames = 200;
  std::vector<std::unique_ptr<Client>> clients;
  for (int i = 0; i < kReaders + 1; ++i) clients.push_back(std::make_unique<Client>(server.port()));
  for (auto& c : clients) c->read();  // the hello
  while (server.stats().clients < kReaders + 1) std::this_thread::sleep_for(std::chrono::milliseconds(1));
  std::vector<std::atomic<int>> received(kReaders);
  std::atomic<bool> done{false};
  std::vector<std::thread> readers;
  for (int i = 0; i < kReaders; ++i) {
    readers.emplace_back([&, i] {
      try {
        while (received[i] < kFrames) {
          clients[i]->read();
          ++received[i];
        }
      } catch (const std::exception&) {
      }
    });
  }
  // 200 frames of 100 kB (a frame set at level of detail 1) at 60 per second: 20 MB, far more
  // than a stalled socket's buffers hold. A frame is sent only once every reader has all but the
  // last 4 of those before it (60 s at most in all; 3.3 s when nothing waits, and ThreadSanitizer
  // slows the readers several times over): a reader thread starved of the CPU by other tests
  // (make test runs two at once on two cores) would otherwise fall more than the 8 waiting frames
  // behind, and be skipped as a slow client, rightly. If the stalled client held up the others,
  // they would stop receiving and the wait would run out; a broadcast that sent instead of handing
  // over would block on the stalled socket and the test would not end.
  const std::string frame = frame_message("{}", std::string(100 * 1024, 'm'));
  const auto readers_deadline = std::chrono::steady_clock::now() + std::chrono::seconds(60);
  for (int k = 0; k < kFrames; ++k) {
    for (int i = 0; i < kReaders; ++i) {
      while (received[i] < k - 4 && std::chrono::steady_clock::now() < readers_deadline) std::this_thread::sleep_for(std::chrono::milliseconds(1));
    }
    server.broadcast(frame);
    std::this_thread::sleep_for(std::chrono::microseconds(16667));
  }
  const auto deadline = std::chrono::steady_clock::now() + std::chrono::seconds(20);
  for (int i = 0; i < kReaders; ++i) {
    while (received[i] < kFrames && std::chrono::steady_clock::now() < deadline) std::this_thread::sleep_for(std::chrono::milliseconds(5));
  }
  done = true;
  for (int i = 0; i < kReaders; ++i) EXPECT_EQ(received[i], kFrames) << "reader " << i;
  // A reader still blocked in a read (one that missed frames) is woken by shutting its socket
  // down, not closing it: a read blocked on a closed socket need not return. Through the
  // descriptor: the Asio socket object is the reader's while it reads, and closing it from this
  // thread would race with that read (ThreadSanitizer's report). Closed once the readers are done.
  for (int i = 0; i < kReaders; ++i) ::shutdown(clients[i]->ws.next_layer().native_handle(), SHUT_RDWR);
  for (auto& t : readers) t.join();
  const StreamServerStats stats = server.stats();
  EXPECT_GT(stats.frames_skipped, kFrames / 2) << "the stalled client should skip most frames";
}

}  // namespace
}  // namespace zipfusion
