#pragma once
//! \file
//! The live stream (issue 8): one HTTP port serves the viewer's files and a WebSocket stream of
//! frames (Boost.Beast). A frame is one binary message, `frame_message`: a small JSON header
//! (frame number, capture time, stats) and the Draco-compressed mesh. A client first receives
//! the stream's description (a text message: the rig, the volume, the frame rate).
//!
//! Every client has its own bounded queue: when a client reads slower than frames come, its
//! oldest waiting frames are skipped, so it never slows the pipeline or the other clients.
//! A client's messages to the server are small JSON commands ({"type": "pause" | "resume" |
//! "ping"}, and for flow control {"type": "flow", "window": N}, at any time, then {"type": "ack"}
//! once per frame received: at most N frames are then unacknowledged and the newest waits, so a
//! viewer slower than the stream sees the newest frame, not a backlog in the network buffers); an oversized or
//! malformed one closes that client only. With a token, the page and
//! the stream refuse requests that carry neither ?token=... nor the cookie the page sets.
//!
//! Thread safety: broadcast() and stats() may be called from any thread; the network runs on the
//! server's own thread.

#include <atomic>
#include <cstdint>
#include <filesystem>
#include <memory>
#include <optional>
#include <string>
#include <string_view>

namespace zipfusion {

struct StreamServerOptions {
  std::string bind_address = "127.0.0.1";  // loopback unless told otherwise
  int port = 8080;                         // 0: any free port (see StreamServer::port)
  std::string token;                       // non-empty: clients must present it
  std::filesystem::path web_root;          // the viewer's files; empty: no page, the stream only
  int client_queue_frames = 2;             // frames waiting per client before the oldest is skipped
  int max_client_message_bytes = 1024;     // a longer message from a client closes it

  void validate() const;  // throws InvalidInput naming the option
};

struct StreamServerStats {
  int clients = 0;               // connected WebSocket clients now
  long clients_total = 0;        // accepted since the start
  long refused = 0;              // requests refused for a missing or wrong token
  long closed_bad_message = 0;   // clients closed for an oversized or malformed message
  long frames_broadcast = 0;     // frames handed to broadcast()
  long frames_sent = 0;          // frame messages written to clients, all clients together
  long frames_skipped = 0;       // frame messages a slow client skipped
  long bytes_sent = 0;
};

//! A client's command, as the server understands it.
struct ClientCommand {
  enum class Type { kPause, kResume, kFlow, kAck, kPing };
  Type type = Type::kPing;
  int flow_window = 0;   // kFlow: at most this many frames unacknowledged (1..8); 0 turns flow control off
  std::string pong;      // kPing: the reply, as JSON text: {"type": "pong"} and the ping's "t" member, if any, echoed
};

//! Parses a client's text message (untrusted bytes from the network); nullopt when it is not a
//! command: not JSON, not an object, an unknown type, a window outside 0..8.
std::optional<ClientCommand> parse_client_command(std::string_view text);

//! The frame message: "ZFM1", the header's length (uint32, little-endian), the JSON header, the
//! Draco bytes.
std::string frame_message(const std::string& header_json, const std::string& draco_bytes);

//! The host part of a URL for a bind address: an IPv6 address in brackets (RFC 3986), or its
//! colons would read as the port's, with the '%' before a zone id written as "%25" (RFC 6874).
std::string url_host(const std::string& address);

class StreamServer {
 public:
  //! Binds and starts serving on its own thread. `hello_json` is sent to every client first.
  //! Throws InvalidInput for bad options and IoError naming address:port when it cannot bind.
  StreamServer(const StreamServerOptions& options, std::string hello_json);
  ~StreamServer();  // stops and joins the thread
  StreamServer(const StreamServer&) = delete;
  StreamServer& operator=(const StreamServer&) = delete;

  int port() const;  // the port bound (useful with port 0)

  //! Replaces the hello: sent to the clients connected now and to every one that connects after
  //! (`serve`: the poses refined after the server started). Thread-safe; returns at once.
  void set_hello(std::string hello_json);

  //! Queues a frame message for every connected client; returns at once.
  void broadcast(std::string message);

  //! Whether some client would be sent one more frame at once (connected, not paused, its flow
  //! window not full), counting the frames reserved before and not yet broadcast (against the
  //! largest room of any one client); if so, reserves a place for it. Every true must be followed
  //! by exactly one broadcast(), which spends it (a broadcast without one spends another's). A
  //! stream makes only the frames reserved: a viewer slower than the stream, alone, is sent a
  //! frame begun after it asked rather than one that aged while it was busy, and with nobody
  //! watching no frame is made.
  bool reserve_frame();

  StreamServerStats stats() const;

  struct Impl;

 private:
  std::unique_ptr<Impl> impl_;
};

}  // namespace zipfusion
