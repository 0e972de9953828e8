// libFuzzer target: a viewer's WebSocket commands to `serve` (stream/stream_server.h), untrusted
// bytes from the network. What parses must be a command the server can act on (a flow window in
// 0..8, a pong that is JSON with the ping's "t") and parse again, unchanged, from the text a viewer would send.

#include <cstddef>
#include <cstdint>
#include <string>
#include <string_view>

#include <nlohmann/json.hpp>

#include "fuzz/fuzz_check.h"
#include "zipfusion/stream/stream_server.h"

namespace zipfusion::fuzz {
namespace {

// The command as the viewer (web/src/viewer.js) writes it.
std::string viewer_text(const ClientCommand& c) {
  switch (c.type) {
    case ClientCommand::Type::kPause: return R"({"type":"pause"})";
    case ClientCommand::Type::kResume: return R"({"type":"resume"})";
    case ClientCommand::Type::kFlow: return R"({"type":"flow","window":)" + std::to_string(c.flow_window) + "}";
    case ClientCommand::Type::kAck: return R"({"type":"ack"})";
    case ClientCommand::Type::kPing: {
      nlohmann::json ping = nlohmann::json::parse(c.pong);
      ping["type"] = "ping";
      return ping.dump();
    }
  }
  fail("a command of no known type");
}

void check_command(std::string_view text) {
  const std::optional<ClientCommand> command = parse_client_command(text);
  if (!command) {
    if (decoder_that_must_accept() == "command") fail("a valid command was refused");
    return;
  }
  if (command->flow_window < 0 || command->flow_window > 8) fail("a flow window outside 0..8");
  if (command->type == ClientCommand::Type::kPing) {
    const nlohmann::json pong = nlohmann::json::parse(command->pong, nullptr, false);
    if (!pong.is_object() || pong.value("type", "") != "pong" || pong.size() > 2 || (pong.size() == 2 && !pong.contains("t"))) {
      fail("a pong that is not {\"type\": \"pong\"} with at most the ping's t: " + command->pong);
    }
  }
  const std::optional<ClientCommand> again = parse_client_command(viewer_text(*command));
  if (!again || again->type != command->type || again->flow_window != command->flow_window || again->pong != command->pong) {
    fail("the command does not parse again from the viewer's text: " + viewer_text(*command));
  }
}

}  // namespace
}  // namespace zipfusion::fuzz

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
  zipfusion::fuzz::check_command(std::string_view(reinterpret_cast<const char*>(data), size));
  return 0;
}
