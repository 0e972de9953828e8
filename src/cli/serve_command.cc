// zipfusion serve: the live stream of a capture (issue 8). Frames are played at the capture's
// frame rate, reconstructed, compressed with Draco and streamed over one HTTP port to the viewer
// in the browser (web/, served from the same port).

#include <algorithm>
#include <chrono>
#include <cstdio>
#include <filesystem>
#include <iostream>
#include <memory>
#include <nlohmann/json.hpp>
#include <thread>

#include "cli/commands.h"
#include "cli/frame_input.h"
#include "cli/reconstruction_setup.h"
#include "zipfusion/core/error.h"
#include "zipfusion/core/stopwatch.h"
#include "zipfusion/io/draco_codec.h"
#include "zipfusion/io/file_util.h"
#include "zipfusion/stream/stream_server.h"

namespace zipfusion::cli {
namespace {

namespace fs = std::filesystem;
using Clock = std::chrono::steady_clock;

struct ServeArgs {
  InputArgs input;
  bool loop = false;
  StreamServerOptions server;
  std::string web;
  DracoOptions draco;
  ReconstructionArgs reconstruction;
};


double epoch_ms() {
  return std::chrono::duration<double, std::milli>(std::chrono::system_clock::now().time_since_epoch()).count();
}

// The viewer's files: --web, or web/ next to the executable (the build puts it there).
fs::path viewer_folder(const std::string& web) {
  if (!web.empty()) return web;
  std::error_code ec;
  const fs::path exe = fs::read_symlink("/proc/self/exe", ec);
  return ec ? fs::path("web") : exe.parent_path() / "web";
}

// What a viewer learns first: the stream's format, frame rate, cameras (for the views from
// each camera) and volume.
std::string hello_json(const Rig& rig, const ServeArgs& args, const QuantizationBox& box) {
  nlohmann::ordered_json cameras = nlohmann::json::array();
  for (const CameraModel& cam : rig.cameras) {
    const Intrinsics& k = cam.depth_intrinsics;
    cameras.push_back({{"name", cam.name},
                       {"world_from_depth", matrix_json(cam.world_from_depth)},
                       {"intrinsics", {{"width", k.width}, {"height", k.height}, {"fx", k.fx}, {"fy", k.fy}, {"cx", k.cx}, {"cy", k.cy}}}});
  }
  nlohmann::ordered_json hello = {{"type", "hello"},
                                  {"format", "zipfusion.stream/1"},
                                  {"capture", args.input.live ? std::string("live") : folder_path(args.input.capture).filename().string()},  // "cap/" too
                                  {"fps", rig.fps},
                                  {"lod", args.reconstruction.options.depth_level},
                                  {"position_bits", args.draco.position_bits},
                                  {"quantization_step_m", box.step(args.draco.position_bits)},
                                  {"cameras", cameras}};
  if (rig.volume) {
    hello["volume"] = {{"min", {rig.volume->min.x(), rig.volume->min.y(), rig.volume->min.z()}},
                       {"max", {rig.volume->max.x(), rig.volume->max.y(), rig.volume->max.z()}}};
  }
  return json_text(hello);
}

// Frame sets at the capture's frame rate, like a live camera: frame i is handed over at
// start + i / fps (a slow pipeline drops the oldest; the source never waits for it). With --loop
// the range repeats, decoded once and replayed from memory.
class PacedSource {
 public:
  PacedSource(const Capture& capture, const FrameRange& range, bool loop, double seconds)
      : capture_(capture), range_(range), loop_(loop), period_(1.0 / capture.rig().fps), seconds_(seconds) {}

  // The pipeline's FrameSource: the next frame set into `set` (its buffers reused), when it is due.
  bool next(FrameSet& set, double& decode_ms) {
    if (stop_requested()) return false;
    const int count = range_.end - range_.begin;
    if (!loop_ && sequence_ >= count) return false;
    const int index = range_.begin + static_cast<int>(sequence_ % count);
    const Clock::time_point due = start_ + std::chrono::duration_cast<Clock::duration>(std::chrono::duration<double>(sequence_ * period_));
    if (seconds_ > 0 && std::chrono::duration<double>(due - start_).count() >= seconds_) return false;
    decode_ms = 0;
    if (loop_ && static_cast<int>(cache_.size()) == count) {
      set = cache_[index - range_.begin];
    } else {
      const Clock::time_point t = Clock::now();
      reader_.read(index, set);
      decode_ms = ms_since(t);
      unreadable_.report(capture_.rig(), set);
      if (loop_) cache_.push_back(set);
    }
    // Waits in short steps: Ctrl-C must stop a capture of a few frames per second (or fewer) at once.
    for (Clock::time_point now = Clock::now(); now < due; now = Clock::now()) {
      if (stop_requested()) return false;
      std::this_thread::sleep_until(std::min(due, now + std::chrono::milliseconds(50)));
    }
    ++sequence_;
    set.capture_time_ms = epoch_ms();  // now is when a camera would have delivered it
    return true;
  }

 private:
  const Capture& capture_;
  FrameRange range_;
  bool loop_;
  double period_;
  double seconds_;
  const Clock::time_point start_ = Clock::now();
  long sequence_ = 0;
  FrameSetReader reader_{capture_};
  std::vector<FrameSet> cache_;
  UnreadableFrames unreadable_{"serve"};
};

void run_serve(ServeArgs& args) {
  args.draco.validate();
  args.server.web_root = viewer_folder(args.web);
  args.server.validate();
  if (args.input.live && args.loop && args.input.devices.replay.empty()) throw InvalidInput("--loop: only for a capture or --replay");
  // A stream of recordings plays as the devices delivered them, as a capture plays at its rate.
  args.input.devices.replay_paced = true;
  args.input.devices.replay_loop = args.loop;
  ReconstructionArgs& r = args.reconstruction;
  Input in;
  open_input(args.input, r.rig, "serve", in);
  warn_if_world_not_z_up(in.rig, r, "serve");
  apply_reconstruction_args(r);  // a bad option is said before the address is
  // One quantisation grid for the whole stream: the capture volume (a mesh reaching outside it
  // grows the grid of that frame only).
  const QuantizationBox volume_box = quantization_box(TriangleMesh{}, in.rig.volume);
  // Served before the poses are refined (seconds): a port in use is said at once, and a viewer
  // can connect meanwhile; its hello is replaced where the refinement moved the cameras.
  StreamServer server(args.server, hello_json(in.rig, args, volume_box));

  install_stop_on_signal();
  const std::string& host = args.server.bind_address;
  // Bound to every interface, the URL names this machine as others reach it, not 0.0.0.0.
  const bool everywhere = host == "0.0.0.0" || host == "::";
  std::string url = "http://" + (everywhere ? host_name() : url_host(host)) + ":" + std::to_string(server.port()) + "/";
  if (!args.server.token.empty()) url += "?token=" + args.server.token;
  std::cout << "serving " << url << " (" << in.rig.cameras.size() << " cameras, " << in.rig.fps << " fps, lod "
            << r.options.depth_level << (args.loop ? ", looping" : "") << "; Ctrl-C stops)" << std::endl;
  Reconstruction reconstruction(in.rig, in.capture ? &*in.capture : nullptr, r, in.range, in.take_before_start);
  reconstruction.say_how_far_poses_moved("serve");
  if (!reconstruction.pose_updates().empty()) server.set_hello(hello_json(reconstruction.rig(), args, volume_box));

  // A capture plays at its frame rate; live cameras deliver at theirs. Either way a frame set's
  // capture time is when it is handed over.
  std::unique_ptr<PacedSource> paced;
  FrameSource source;
  if (in.capture) {
    paced = std::make_unique<PacedSource>(*in.capture, in.range, args.loop, args.input.seconds);
    source = [&](FrameSet& set, double& decode_ms) { return paced->next(set, decode_ms); };
  } else {
    source = [&](FrameSet& set, double& decode_ms) {
      if (!in.source(set, decode_ms)) return false;
      set.capture_time_ms = epoch_ms();
      return true;
    };
  }
  PipelineOptions pipeline_options = reconstruction.pipeline_options();
  pipeline_options.source_policy = QueuePolicy::kDropOldest;  // live: never fall behind
  pipeline_options.queue_depth = 1;
  // Only the frames some viewer can be sent at once are made: a viewer slower than the stream
  // then gets a frame made for it when it is ready, not one that aged while it was busy, and the
  // CPU it leaves (a browser drawing in software on the same machine) goes to drawing.
  pipeline_options.wants_frame = [&] { return server.reserve_frame(); };  // the sink broadcasts each frame made
  pipeline_options.take_when_sink_ready = true;

  double last_report = epoch_ms();
  long frames_since = 0, bytes_since = 0;
  std::vector<int> remap;  // remove_unreferenced_vertices' scratch
  const PipelineStats stats = run_pipeline(source, reconstruction.reconstructor(), [&](PipelineFrame& frame) {
    remove_unreferenced_vertices(frame.result.mesh, remap);
    const Clock::time_point t = Clock::now();
    const std::string draco = encode_draco(frame.result.mesh, quantization_box(frame.result.mesh, reconstruction.rig().volume), args.draco);
    const double encode_ms = ms_since(t);
    const nlohmann::ordered_json header = {{"type", "frame"},
                                           {"frame", frame.index},
                                           {"sequence", frame.sequence},  // the stream's frames before this one, made or not
                                           {"capture_time_ms", frame.capture_time_ms},
                                           {"sent_time_ms", epoch_ms()},
                                           {"triangles", frame.result.mesh.triangle_count()},
                                           {"vertices", frame.result.mesh.vertex_count()},
                                           {"cameras_used", frame.result.cameras_used},
                                           {"reconstruct_ms", frame.result.times.total_ms},
                                           {"encode_ms", encode_ms},
                                           {"bytes", draco.size()}};
    server.broadcast(frame_message(header.dump(), draco));
    ++frames_since;
    bytes_since += static_cast<long>(draco.size());
    const double now = epoch_ms();
    if (now - last_report > 5000) {
      const StreamServerStats s = server.stats();
      std::printf("frame %d: %.1f fps, %.0f kB/frame (%.1f Mbit/s), %d clients, %ld frames skipped by slow clients\n", frame.index,
                  frames_since * 1000.0 / (now - last_report), bytes_since / 1024.0 / std::max(1L, frames_since),
                  bytes_since * 8e-3 / (now - last_report), s.clients, s.frames_skipped);
      std::fflush(stdout);
      last_report = now;
      frames_since = bytes_since = 0;
    }
  }, pipeline_options);
  const StreamServerStats s = server.stats();
  std::printf("served %d frame sets (%ld dropped by the pipeline to keep up, %ld not made: no viewer ready for them), %ld frames to %ld clients "
              "(%ld skipped by slow clients), %.1f MB\n",
              stats.frames, stats.dropped, stats.unwanted, s.frames_sent, s.clients_total, s.frames_skipped, s.bytes_sent / 1e6);
}

}  // namespace

void add_serve_command(CLI::App& app) {
  auto args = std::make_shared<ServeArgs>();
  args->reconstruction.options.depth_level = 1;  // a stream wants a quarter of the triangles (issue 8's budget)
  CLI::App* cmd = app.add_subcommand("serve", "Stream the reconstruction live to a viewer in the browser");
  add_input_options(cmd, args->input);
  cmd->add_flag("--loop", args->loop, "Play the capture's frames again and again (decoded once, kept in memory), or the --replay dumps");
  cmd->add_option("--port", args->server.port, "HTTP port for the viewer and the stream (0: any free port)")->capture_default_str();
  cmd->add_option("--bind", args->server.bind_address, "Address to listen on (127.0.0.1: this machine only; 0.0.0.0: every network)")
      ->capture_default_str();
  CLI::Option* token = cmd->add_option("--token", args->server.token, "Refuse clients that do not give this token (open the page as /?token=...)");
  cmd->add_option("--web", args->web, "Folder of the viewer's files (default: web/ beside the executable)");
  cmd->add_option("--position-bits", args->draco.position_bits, "Draco: bits per coordinate over the capture volume")->capture_default_str();
  cmd->add_option("--compression-level", args->draco.compression_level, "Draco: 0 (fastest) to 10 (smallest)")->capture_default_str();
  add_reconstruction_options(cmd, args->reconstruction);
  cmd->callback([args, token] {
    // An empty token would let every client in: a script's unset variable, not a choice.
    if (token->count() > 0 && args->server.token.empty()) throw InvalidInput("--token: must not be empty (leave it out to let any client in)");
    run_serve(*args);
  });
}

}  // namespace zipfusion::cli
