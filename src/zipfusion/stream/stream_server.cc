#include "zipfusion/stream/stream_server.h"

#include <utility>  // before Asio: Boost 1.74's awaitable.hpp uses std::exchange without it

#include <boost/asio.hpp>
#include <boost/beast/core.hpp>
#include <boost/beast/http.hpp>
#include <boost/beast/websocket.hpp>
#include <nlohmann/json.hpp>

#include <deque>
#include <fstream>
#include <set>
#include <sstream>
#include <thread>

#include "zipfusion/core/error.h"

namespace zipfusion {
namespace {

namespace net = boost::asio;
namespace beast = boost::beast;
namespace http = beast::http;
namespace websocket = beast::websocket;
using tcp = net::ip::tcp;

constexpr const char* kTokenCookie = "zf_token";

// Constant-time comparison: the time a wrong token takes to refuse tells nothing about the right one.
bool same_secret(const std::string& a, const std::string& b) {
  unsigned char diff = a.size() == b.size() ? 0 : 1;
  for (size_t i = 0; i < a.size() && i < b.size(); ++i) diff |= static_cast<unsigned char>(a[i] ^ b[i]);
  return diff == 0;
}

// The value of `key` in "a=1&token=xyz" (a query, separator '&') or "a=1; zf_token=xyz" (a
// cookie header, ';'), or "".
std::string field_value(const std::string& text, const std::string& key, char separator) {
  std::istringstream in(text);
  std::string item;
  while (std::getline(in, item, separator)) {
    const size_t start = item.find_first_not_of(' ');
    if (start == std::string::npos) continue;
    const size_t eq = item.find('=', start);
    if (eq != std::string::npos && item.compare(start, eq - start, key) == 0) return item.substr(eq + 1);
  }
  return "";
}

// Is `host` (a Host header: name or address, optional port) this machine's loopback?
bool loopback_host(const std::string& host) {
  std::string name = host;
  if (!name.empty() && name.front() == '[') {
    name = name.substr(1, name.find(']') - 1);  // [::1]:8080
  } else if (std::count(name.begin(), name.end(), ':') == 1) {
    name = name.substr(0, name.find(':'));
  }
  if (name == "localhost") return true;
  // An address literal only: a name such as "127.attacker.example" is a DNS name that an attacker
  // can point at this machine, which is what the check is for.
  boost::system::error_code error;
  const net::ip::address address = net::ip::make_address(name, error);
  return !error && address.is_loopback();
}

const char* content_type(const std::filesystem::path& file) {
  const std::string ext = file.extension().string();
  if (ext == ".html") return "text/html; charset=utf-8";
  if (ext == ".js" || ext == ".mjs") return "text/javascript; charset=utf-8";
  if (ext == ".wasm") return "application/wasm";
  if (ext == ".json") return "application/json";
  if (ext == ".css") return "text/css; charset=utf-8";
  return "application/octet-stream";
}

// A path of the request that names a file of the viewer: plain names in the root or one folder
// below it, nothing else (no "..", no hidden files, no absolute paths).
bool safe_relative_path(const std::string& path) {
  if (path.empty() || path.size() > 200) return false;
  int slashes = 0;
  char previous = '/';
  for (const char c : path) {
    const bool plain = std::isalnum(static_cast<unsigned char>(c)) || c == '_' || c == '-' || c == '.';
    if (c == '/') {
      if (previous == '/' || ++slashes > 1) return false;
    } else if (!plain || (c == '.' && previous == '/')) {
      return false;
    }
    previous = c;
  }
  return previous != '/';
}

struct Session;

}  // namespace

// Clients at most: beyond, a connection is refused (each costs a socket and a queue of frames).
constexpr int kMaxClients = 64;
// Text messages (the hello, pongs) a client may have waiting: more means it sends commands and
// does not read, and it is closed.
constexpr int kMaxWaitingReplies = 8;
constexpr int kUnlimitedRoom = 1 << 20;  // a client without flow control takes every frame

void decrement_if_positive(std::atomic<int>& count) {
  int value = count;
  while (value > 0 && !count.compare_exchange_weak(value, value - 1)) {
  }
}

struct StreamServer::Impl {
  StreamServerOptions options;
  int port = 0;
  std::string hello;
  net::io_context io{1};
  tcp::acceptor acceptor{io};
  net::steady_timer accept_retry{io};
  std::set<std::shared_ptr<Session>> sessions;  // touched on the io thread only
  std::thread thread;
  std::atomic<long> clients_total{0}, refused{0}, closed_bad_message{0}, frames_broadcast{0}, frames_sent{0}, frames_skipped{0}, bytes_sent{0};
  std::atomic<int> clients{0};
  // WebSocket handshakes under way (network thread only): they count against kMaxClients too, or
  // upgrades arriving together would all pass the check before any became a client.
  int handshaking = 0;
  // Frames a client could be sent at once, the most over the clients (see Session::room), and
  // frames reserved for it (reserve_frame) that broadcast() has not handed on yet.
  std::atomic<int> most_room{0}, frames_reserved{0};

  void accept();
  void update_room();  // on the network thread, after any change of a session's room
  bool authorised(const http::request<http::string_body>& request, const std::string& query) const;
  bool same_origin(const http::request<http::string_body>& request) const;
};

namespace {

// One WebSocket client: its queue of messages waiting to be written, one write at a time.
struct Session : std::enable_shared_from_this<Session> {
  Session(tcp::socket socket, StreamServer::Impl& owner) : ws(std::move(socket)), server(owner) {}

  void start(http::request<http::string_body> request) {
    ws.set_option(websocket::stream_base::timeout::suggested(beast::role_type::server));
    ws.read_message_max(static_cast<std::uint64_t>(server.options.max_client_message_bytes));
    ++server.handshaking;
    ws.async_accept(request, [self = shared_from_this()](beast::error_code ec) {
      --self->server.handshaking;
      if (ec) return;
      self->server.sessions.insert(self);
      self->server.update_room();
      self->server.clients = static_cast<int>(self->server.sessions.size());
      ++self->server.clients_total;
      self->enqueue(std::make_shared<const std::string>(self->server.hello), false);
      self->read();
    });
  }

  // Queues a message; a full queue skips its oldest frame not being written. A client with a
  // flow window is sent a frame only while fewer than `window` are unacknowledged; meanwhile
  // the newest frame waits and replaces older ones.
  void enqueue(std::shared_ptr<const std::string> message, bool binary) {
    if (closed || (binary && paused)) return;
    if (binary && window > 0) {
      if (in_flight >= window) {
        if (held) ++server.frames_skipped;
        held = std::move(message);
        return;
      }
      ++in_flight;
      server.update_room();
    }
    // A frame that goes out is newer than one still held (the window has grown since it was
    // held): sent after it, the held one would step back in time.
    if (binary && held) {
      held.reset();
      ++server.frames_skipped;
    }
    const size_t first_waiting = writing ? 1 : 0;
    if (!binary && std::count_if(queue.begin(), queue.end(), [](const auto& m) { return !m.second; }) >= kMaxWaitingReplies) {
      return refuse("commands sent faster than the replies are read");
    }
    if (binary && static_cast<int>(queue.size() - first_waiting) >= server.options.client_queue_frames) {
      for (size_t i = first_waiting; i < queue.size(); ++i) {
        if (queue[i].second) {
          queue.erase(queue.begin() + static_cast<long>(i));
          ++server.frames_skipped;
          if (window > 0 && in_flight > 0) --in_flight;  // never sent, so never acknowledged
          server.update_room();
          break;
        }
      }
    }
    queue.emplace_back(std::move(message), binary);
    if (!writing) write_next();
  }

  void write_next() {
    if (queue.empty() || closed) {
      writing = false;
      return;
    }
    writing = true;
    ws.binary(queue.front().second);
    ws.async_write(net::buffer(*queue.front().first), [self = shared_from_this()](beast::error_code ec, size_t bytes) {
      if (ec) return self->finish();
      if (self->queue.front().second) {
        ++self->server.frames_sent;
        self->server.bytes_sent += static_cast<long>(bytes);
      }
      self->queue.pop_front();
      self->write_next();
    });
  }

  void read() {
    ws.async_read(incoming, [self = shared_from_this()](beast::error_code ec, size_t) {
      if (ec == websocket::error::message_too_big) {  // Beast has closed it already, with code 1009 ("too big")
        ++self->server.closed_bad_message;
        return self->finish();
      }
      if (ec) return self->finish();
      const std::string text = beast::buffers_to_string(self->incoming.data());
      self->incoming.consume(self->incoming.size());
      if (!self->handle(text)) return self->refuse("malformed message");
      self->server.update_room();
      self->read();
    });
  }

  // A command from the client; false when it is not one.
  bool handle(const std::string& text) {
    if (!ws.got_text()) return false;
    std::optional<ClientCommand> command = parse_client_command(text);
    if (!command) return false;
    switch (command->type) {
      case ClientCommand::Type::kPause:
        paused = true;
        break;
      case ClientCommand::Type::kResume:
        paused = false;
        break;
      case ClientCommand::Type::kFlow:
        window = command->flow_window;
        release_held();  // a larger window (or none) has room for it now
        break;
      case ClientCommand::Type::kAck:
        // A frame was drawn (or decoded, or skipped): the newest held frame may go.
        if (in_flight > 0) --in_flight;
        release_held();
        break;
      case ClientCommand::Type::kPing:
        enqueue(std::make_shared<const std::string>(std::move(command->pong)), false);
        break;
    }
    return true;
  }

  // Sends the held frame if the window has room for it.
  void release_held() {
    if (!held || (window > 0 && in_flight >= window)) return;
    std::shared_ptr<const std::string> next = std::move(held);
    held.reset();
    enqueue(std::move(next), true);
  }

  // Closes this client only, saying why.
  void refuse(const char* why) {
    if (closed) return;
    ++server.closed_bad_message;
    closed = true;
    server.update_room();  // the close handshake may take a while: no frames are made for it
    ws.async_close(websocket::close_reason(websocket::close_code::policy_error, why), [self = shared_from_this()](beast::error_code) { self->finish(); });
  }

  // Frames this client would be sent at once: none while paused, as many as its flow window has
  // room for, or any number without flow control (its queue skips what it cannot read).
  int room() const {
    if (closed || paused) return 0;
    if (window == 0) return kUnlimitedRoom;
    return std::max(0, window - in_flight);
  }

  void finish() {
    closed = true;
    server.sessions.erase(shared_from_this());
    server.clients = static_cast<int>(server.sessions.size());
    server.update_room();
  }

  websocket::stream<beast::tcp_stream> ws;
  StreamServer::Impl& server;
  beast::flat_buffer incoming;
  std::deque<std::pair<std::shared_ptr<const std::string>, bool>> queue;  // message, binary (a frame)
  bool writing = false, paused = false, closed = false;
  int window = 0, in_flight = 0;               // flow control (0: off)
  std::shared_ptr<const std::string> held;     // with a full window: the newest frame, waiting for an ack
};

// One HTTP connection: files of the viewer, or the upgrade to the stream.
struct HttpSession : std::enable_shared_from_this<HttpSession> {
  HttpSession(tcp::socket socket, StreamServer::Impl& owner) : stream(std::move(socket)), server(owner) {}

  void read() {
    parser.emplace();
    parser->header_limit(8 * 1024);
    parser->body_limit(8 * 1024);
    stream.expires_after(std::chrono::seconds(30));
    http::async_read(stream, buffer, *parser, [self = shared_from_this()](beast::error_code ec, size_t) {
      if (!ec) return self->respond(self->parser->release());
      // A request that is not HTTP, or too large, gets the reason before the connection closes;
      // a client that went away or stayed silent (end of stream, timeout) gets nothing.
      if (ec.category() != http::make_error_code(http::error::bad_method).category() || ec == http::error::end_of_stream) return;
      http::request<http::string_body> unread;  // HTTP/1.1, for the reply's version
      if (ec == http::error::header_limit) return self->send(self->text_response(unread, http::status::request_header_fields_too_large, "request header too large"));
      if (ec == http::error::body_limit) return self->send(self->text_response(unread, http::status::payload_too_large, "request body too large"));
      self->send(self->text_response(unread, http::status::bad_request, "not an HTTP request: " + ec.message()));
    });
  }

  void respond(http::request<http::string_body> request) {
    const std::string target(request.target());
    if (target.empty() || target.front() != '/') return send(text_response(request, http::status::bad_request, "bad request target"));
    // HTTP/1.1 requires a Host (RFC 9112); an HTTP/1.0 client (wget, a script) may leave it out.
    if (request[http::field::host].empty() && request.version() >= 11) {
      return send(text_response(request, http::status::bad_request, "a Host header is required"));
    }
    if (!server.same_origin(request)) return send(text_response(request, http::status::forbidden, "another site's page may not use this stream"));
    if (server.clients + server.handshaking >= kMaxClients && websocket::is_upgrade(request)) {
      return send(text_response(request, http::status::service_unavailable, "too many viewers"));
    }
    const size_t question = target.find('?');
    const std::string path = target.substr(0, question), query = question == std::string::npos ? "" : target.substr(question + 1);
    if (!server.authorised(request, query)) {
      ++server.refused;
      return send(text_response(request, http::status::unauthorized, "a token is required: open the page as /?token=..."));
    }
    if (path == "/stream" && websocket::is_upgrade(request)) {
      stream.expires_never();
      std::make_shared<Session>(stream.release_socket(), server)->start(std::move(request));
      return;
    }
    if (request.method() != http::verb::get && request.method() != http::verb::head) {
      return send(text_response(request, http::status::method_not_allowed, "GET only"));
    }
    if (path == "/stream") {
      // The stream, asked for without the WebSocket upgrade (curl, a browser's address bar).
      auto response = text_response(request, http::status::upgrade_required, "the stream is a WebSocket: open / for the viewer");
      response->set(http::field::upgrade, "websocket");
      response->set(http::field::connection, "Upgrade, close");
      return send(response);
    }
    const std::string relative = path == "/" ? "index.html" : path.substr(1);
    if (server.options.web_root.empty() || !safe_relative_path(relative)) return send(text_response(request, http::status::not_found, "not found"));
    const std::filesystem::path file = server.options.web_root / relative;
    std::error_code ec;
    std::ifstream in(file, std::ios::binary);
    if (!std::filesystem::is_regular_file(file, ec) || !in) return send(text_response(request, http::status::not_found, "not found"));
    std::ostringstream body;
    body << in.rdbuf();
    auto response = std::make_shared<http::response<http::string_body>>(http::status::ok, request.version());
    response->set(http::field::content_type, content_type(file));
    response->set(http::field::cache_control, "no-cache");
    // The page's token becomes a cookie, so its scripts and the stream carry it without ?token=.
    if (!server.options.token.empty()) {
      response->set(http::field::set_cookie, std::string(kTokenCookie) + "=" + server.options.token + "; Path=/; HttpOnly; SameSite=Strict");
    }
    response->keep_alive(request.keep_alive());
    response->body() = body.str();
    response->prepare_payload();  // HEAD: the length of the body, which is then not sent
    if (request.method() == http::verb::head) response->body().clear();
    send(response);
  }

  std::shared_ptr<http::response<http::string_body>> text_response(const http::request<http::string_body>& request, http::status status,
                                                                   const std::string& text) {
    auto response = std::make_shared<http::response<http::string_body>>(status, request.version());
    response->set(http::field::content_type, "text/plain; charset=utf-8");
    response->keep_alive(false);
    response->body() = text + "\n";
    response->prepare_payload();
    return response;
  }

  void send(std::shared_ptr<http::response<http::string_body>> response) {
    http::async_write(stream, *response, [self = shared_from_this(), response](beast::error_code ec, size_t) {
      if (ec || !response->keep_alive()) {
        beast::error_code ignored;
        self->stream.socket().shutdown(tcp::socket::shutdown_send, ignored);
        return;
      }
      self->read();
    });
  }

  beast::tcp_stream stream;
  StreamServer::Impl& server;
  beast::flat_buffer buffer;
  std::optional<http::request_parser<http::string_body>> parser;
};

}  // namespace

void StreamServer::Impl::update_room() {
  int most = 0;
  for (const auto& session : sessions) most = std::max(most, session->room());
  most_room = most;
}

void StreamServer::Impl::accept() {
  acceptor.async_accept(io, [this](beast::error_code ec, tcp::socket socket) {
    if (ec == net::error::operation_aborted) return;
    if (ec) {
      // Out of sockets or the like: try again a little later rather than spin the network thread.
      accept_retry.expires_after(std::chrono::milliseconds(100));
      accept_retry.async_wait([this](beast::error_code wait) {
        if (!wait) accept();
      });
      return;
    }
    // Without it, a frame's last segment waits for the viewer's delayed ACK (40 ms on Linux)
    // whenever an earlier one is unacknowledged: Nagle's algorithm, made for typing.
    beast::error_code ignored;
    socket.set_option(tcp::no_delay(true), ignored);
    std::make_shared<HttpSession>(std::move(socket), *this)->read();
    accept();
  });
}

bool StreamServer::Impl::same_origin(const http::request<http::string_body>& request) const {
  // A page of another site may open a WebSocket to this machine (browsers allow it): refuse
  // requests whose Origin is not this server. Served on loopback, the Host must be loopback too,
  // so a name rebound to 127.0.0.1 by its DNS cannot reach it.
  const std::string host(request[http::field::host]);
  // No Host at all (HTTP/1.0) is no browser's request: browsers always name the host, which is
  // what a rebound name would show.
  if (loopback_host(options.bind_address) && !host.empty() && !loopback_host(host)) return false;
  const std::string origin(request[http::field::origin]);
  return origin.empty() || origin == "http://" + host || origin == "https://" + host;
}

bool StreamServer::Impl::authorised(const http::request<http::string_body>& request, const std::string& query) const {
  if (options.token.empty()) return true;
  return same_secret(field_value(query, "token", '&'), options.token) ||
         same_secret(field_value(std::string(request[http::field::cookie]), kTokenCookie, ';'), options.token);
}

void StreamServerOptions::validate() const {
  if (port < 0 || port > 65535) throw InvalidInput("--port: must be in [0, 65535], got " + std::to_string(port));
  if (client_queue_frames < 1) throw InvalidInput("client queue: must hold at least one frame");
  if (max_client_message_bytes < 16) throw InvalidInput("client message limit: must be at least 16 bytes");
  for (const char c : token) {
    if (!std::isalnum(static_cast<unsigned char>(c)) && c != '-' && c != '_' && c != '.') {
      throw InvalidInput("--token: use letters, digits, '-', '_' or '.' only (it travels in a URL and a cookie)");
    }
  }
  if (!web_root.empty() && !std::filesystem::is_regular_file(web_root / "index.html")) {
    throw InvalidInput((web_root / "index.html").string() + ": the viewer is missing (build it with make build)");
  }
}

std::optional<ClientCommand> parse_client_command(std::string_view text) {
  const nlohmann::json command = nlohmann::json::parse(text, nullptr, false);
  if (!command.is_object() || !command.contains("type") || !command["type"].is_string()) return std::nullopt;
  const std::string& type = command["type"].get_ref<const std::string&>();
  ClientCommand out;
  if (type == "pause") {
    out.type = ClientCommand::Type::kPause;
  } else if (type == "resume") {
    out.type = ClientCommand::Type::kResume;
  } else if (type == "flow") {
    // {"type": "flow", "window": N}: at most N frames unacknowledged (1..8); 0 turns it off. Read
    // wide, then checked: an int would narrow 2^32 + 1 to a window of one. Past int64, the unsigned
    // value wraps negative and is refused too.
    if (!command.contains("window") || !command["window"].is_number_integer()) return std::nullopt;
    const auto n = command["window"].get<std::int64_t>();
    if (n < 0 || n > 8) return std::nullopt;
    out.type = ClientCommand::Type::kFlow;
    out.flow_window = static_cast<int>(n);
  } else if (type == "ack") {
    out.type = ClientCommand::Type::kAck;
  } else if (type == "ping") {
    out.type = ClientCommand::Type::kPing;
    nlohmann::json pong{{"type", "pong"}};
    if (command.contains("t")) pong["t"] = command["t"];
    out.pong = pong.dump();
  } else {
    return std::nullopt;
  }
  return out;
}

std::string url_host(const std::string& address) {
  if (address.find(':') == std::string::npos) return address;
  std::string host = "[";
  for (const char c : address) host += c == '%' ? std::string("%25") : std::string(1, c);
  return host + "]";
}

std::string frame_message(const std::string& header_json, const std::string& draco_bytes) {
  std::string message = "ZFM1";
  const auto length = static_cast<std::uint32_t>(header_json.size());
  for (int shift = 0; shift < 32; shift += 8) message.push_back(static_cast<char>((length >> shift) & 0xff));
  message += header_json;
  message += draco_bytes;
  return message;
}

void StreamServer::set_hello(std::string hello_json) {
  // On the network thread, which alone reads the hello and the sessions.
  net::post(impl_->io, [impl = impl_.get(), hello = std::make_shared<const std::string>(std::move(hello_json))] {
    impl->hello = *hello;
    for (const std::shared_ptr<Session>& session : impl->sessions) session->enqueue(hello, false);
  });
}

StreamServer::StreamServer(const StreamServerOptions& options, std::string hello_json) : impl_(std::make_unique<Impl>()) {
  options.validate();
  impl_->options = options;
  impl_->hello = std::move(hello_json);
  beast::error_code ec;
  const net::ip::address address = net::ip::make_address(options.bind_address, ec);
  if (ec) throw InvalidInput("--bind: \"" + options.bind_address + "\" is not an IP address");
  const tcp::endpoint endpoint(address, static_cast<unsigned short>(options.port));
  const std::string where = options.bind_address + ":" + std::to_string(options.port);
  impl_->acceptor.open(endpoint.protocol(), ec);
  if (!ec) impl_->acceptor.set_option(net::socket_base::reuse_address(true), ec);
  if (!ec) impl_->acceptor.bind(endpoint, ec);
  if (!ec) impl_->acceptor.listen(net::socket_base::max_listen_connections, ec);
  if (ec) throw IoError(where + ": cannot listen: " + ec.message());
  impl_->port = impl_->acceptor.local_endpoint().port();
  impl_->accept();
  impl_->thread = std::thread([impl = impl_.get()] {
    // A handler that throws ends only its own work, never the stream.
    while (true) {
      try {
        impl->io.run();
        return;
      } catch (const std::exception&) {
      }
    }
  });
}

StreamServer::~StreamServer() {
  impl_->io.stop();
  if (impl_->thread.joinable()) impl_->thread.join();
  // The network thread is gone: closing here races with nothing.
  beast::error_code ignored;
  impl_->acceptor.close(ignored);
  for (const auto& session : impl_->sessions) beast::get_lowest_layer(session->ws).close();
  impl_->sessions.clear();
}

int StreamServer::port() const { return impl_->port; }

void StreamServer::broadcast(std::string message) {
  ++impl_->frames_broadcast;
  auto shared = std::make_shared<const std::string>(std::move(message));
  net::post(impl_->io, [impl = impl_.get(), shared] {
    // enqueue may close a session (refuse), which leaves the set only in a later handler.
    for (const auto& session : impl->sessions) session->enqueue(shared, true);
    // The clients' room now counts this frame: its reservation, if it had one, is spent.
    decrement_if_positive(impl->frames_reserved);
  });
}

bool StreamServer::reserve_frame() {
  int reserved = impl_->frames_reserved;
  while (reserved < impl_->most_room) {
    if (impl_->frames_reserved.compare_exchange_weak(reserved, reserved + 1)) return true;
  }
  return false;
}

StreamServerStats StreamServer::stats() const {
  return {impl_->clients.load(), impl_->clients_total.load(), impl_->refused.load(), impl_->closed_bad_message.load(),
          impl_->frames_broadcast.load(), impl_->frames_sent.load(), impl_->frames_skipped.load(), impl_->bytes_sent.load()};
}

}  // namespace zipfusion
