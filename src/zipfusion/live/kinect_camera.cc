#include "zipfusion/live/kinect_camera.h"

#include <dlfcn.h>
#include <libfreenect.h>
#include <libfreenect_registration.h>

#include <algorithm>
#include <atomic>
#include <chrono>
#include <condition_variable>
#include <cstdlib>
#include <cstring>
#include <mutex>
#include <set>
#include <thread>

#include "zipfusion/core/error.h"
#include "zipfusion/live/fakenect_dump.h"
#include "zipfusion/live/kinect_clock.h"
#include "zipfusion/live/kinect_disparity.h"
#include "zipfusion/live/live_frame_queue.h"

namespace zipfusion {
namespace {

using Clock = std::chrono::steady_clock;

double now_s() { return std::chrono::duration<double>(Clock::now().time_since_epoch()).count(); }

constexpr int kLibusbErrorInterrupted = -10;  // LIBUSB_ERROR_INTERRUPTED: a signal, try again

// Functions fakenect's libfreenect.so lacks are looked up at run time, so the same binary runs
// against both libraries (and a call never reaches a missing symbol).
using CopyRegistrationFn = freenect_registration (*)(freenect_device*);
using DestroyRegistrationFn = int (*)(freenect_registration*);
using ListAttributesFn = int (*)(freenect_context*, freenect_device_attributes**);
using FreeAttributesFn = void (*)(freenect_device_attributes*);

template <typename F>
F optional_symbol(const char* name) {
  return reinterpret_cast<F>(::dlsym(RTLD_DEFAULT, name));
}

bool library_registers_depth() { return optional_symbol<CopyRegistrationFn>("freenect_copy_registration") != nullptr; }

// libfreenect logs through this instead of printing: the library never prints.
std::mutex g_log_mutex;
std::string g_last_error;
void log_to_string(freenect_context*, freenect_loglevel level, const char* message) {
  if (level > FREENECT_LOG_ERROR || !message) return;
  std::lock_guard lock(g_log_mutex);
  g_last_error = message;
  while (!g_last_error.empty() && (g_last_error.back() == '\n' || g_last_error.back() == '\r')) g_last_error.pop_back();
}
std::string last_error() {
  std::lock_guard lock(g_log_mutex);
  return g_last_error;
}

// One device's stream: the event thread produces into it, the camera's reader consumes.
struct Slot {
  explicit Slot(int max_queued_frames) : queue(max_queued_frames) {}

  freenect_device* device = nullptr;
  int index = 0;
  std::string serial;
  CameraModel model;
  bool raw = false;
  int width = 640, height = 480;
  double max_color_age_s = 0.04;
  bool started = false;
  std::atomic<bool> stop_requested{false};

  std::mutex mutex;  // guards the consumer-visible state below
  std::condition_variable changed;
  LiveFrameQueue queue;
  bool ended = false;
  std::string end_reason;
  long dropped = 0;

  // Event thread only.
  LiveFrame filling;  // the next depth frame, in the images of a frame read earlier (LiveFrameQueue)
  ColorImage color;
  bool has_color = false;
  std::uint32_t color_timestamp = 0;  // the device clock's, as depth's
  double last_depth_s = 0;
  double opened_s = 0;
  bool had_depth = false;
};

struct Context {
  freenect_context* context = nullptr;
  KinectOptions options;
  double fps = 30;
  std::vector<std::unique_ptr<Slot>> slots;
  std::thread events;
  std::atomic<bool> quit{false};
  // fakenect replays one INDEX.txt line per event call and exits the process at a missing file:
  // the calls it can take, and why no more (-1: no limit).
  long event_calls_left = -1;
  std::string event_limit_reason;

  ~Context() {
    quit = true;
    if (events.joinable()) events.join();
    for (auto& slot : slots) {
      if (!slot->device) continue;
      stop_streams(*slot);
      freenect_close_device(slot->device);
    }
    if (context) freenect_shutdown(context);
  }

  static void end(Slot& slot, const std::string& reason) {
    std::lock_guard lock(slot.mutex);
    if (slot.ended) return;
    slot.ended = true;
    slot.end_reason = reason;
    slot.changed.notify_all();
  }

  void run() {
    while (!quit) {
      bool any_running = false;
      for (auto& slot : slots) {
        std::lock_guard lock(slot->mutex);
        any_running = any_running || !slot->ended;
      }
      if (!any_running) break;
      if (event_calls_left == 0) {
        for (auto& slot : slots) end(*slot, event_limit_reason);
        break;
      }
      if (event_calls_left > 0) --event_calls_left;
      timeval timeout{0, 20000};
      const int status = freenect_process_events_timeout(context, &timeout);
      if (status < 0 && status != kLibusbErrorInterrupted) {
        const std::string detail = last_error();
        const std::string reason = library_registers_depth()
                                       ? "libfreenect stopped delivering (error " + std::to_string(status) + (detail.empty() ? "" : ": " + detail) + ")"
                                       : "end of the fakenect recording";
        for (auto& slot : slots) end(*slot, reason);
        break;
      }
      const double now = now_s();
      for (auto& slot : slots) {
        {
          std::lock_guard lock(slot->mutex);
          if (slot->ended) continue;
        }
        if (slot->stop_requested) {
          end(*slot, "stopped");
          stop_streams(*slot);
        } else if (slot->had_depth ? now - slot->last_depth_s > options.stall_timeout_s : now - slot->opened_s > options.start_timeout_s) {
          char reason[128];
          std::snprintf(reason, sizeof reason, "no depth frame for %.1f s: unplugged or stalled",
                        slot->had_depth ? options.stall_timeout_s : options.start_timeout_s);
          end(*slot, reason);
          stop_streams(*slot);
        }
      }
    }
  }

  // On the event thread only, like every libfreenect call after start-up.
  static void stop_streams(Slot& slot) {
    if (!slot.started) return;
    freenect_stop_depth(slot.device);
    freenect_stop_video(slot.device);
    slot.started = false;
  }

  static void on_video(freenect_device* device, void* data, std::uint32_t timestamp) {
    Slot& slot = *static_cast<Slot*>(freenect_get_user(device));
    if (slot.stop_requested) return;
    slot.color.resize_for_overwrite(slot.width, slot.height);  // every pixel copied below
    std::memcpy(slot.color.data.data(), data, slot.color.data.size() * sizeof(Rgb8));
    slot.color_timestamp = timestamp;
    slot.has_color = true;
  }

  static void on_depth(freenect_device* device, void* data, std::uint32_t timestamp);
};

void Context::on_depth(freenect_device* device, void* data, std::uint32_t timestamp) {
  Slot& slot = *static_cast<Slot*>(freenect_get_user(device));
  if (slot.stop_requested) return;
  LiveFrame& frame = slot.filling;
  if (!frame.holds_images()) {
    // The last push() had no spare to leave here; the reader may have handed one back since.
    std::lock_guard lock(slot.mutex);
    slot.queue.refill(frame);
  }
  frame.time_s = now_s();
  frame.device_timestamp = timestamp;
  frame.depth.resize_for_overwrite(slot.width, slot.height);
  const int n = slot.width * slot.height;
  if (slot.raw) {
    kinect_raw_bytes_to_mm(n, data, frame.depth.data.data());
  } else {
    std::memcpy(frame.depth.data.data(), data, static_cast<size_t>(n) * sizeof(std::uint16_t));
  }
  frame.has_color = slot.has_color && kinect_color_pairs_with_depth(slot.color_timestamp, timestamp, slot.max_color_age_s);
  if (frame.has_color) frame.color = slot.color;  // into the frame's own buffer
  slot.last_depth_s = frame.time_s;
  slot.had_depth = true;
  std::lock_guard lock(slot.mutex);
  if (slot.ended) return;
  if (slot.queue.push(frame)) ++slot.dropped;
  slot.changed.notify_all();
}

class KinectCamera final : public LiveCamera {
 public:
  KinectCamera(std::shared_ptr<Context> context, Slot* slot) : context_(std::move(context)), slot_(slot) {}
  ~KinectCamera() override { stop(); }

  const CameraModel& model() const override { return slot_->model; }
  std::string description() const override {
    return "Kinect v1 #" + std::to_string(slot_->index) + (slot_->serial.empty() ? "" : " (serial " + slot_->serial + ")");
  }
  double fps() const override { return context_->fps; }

  ReadStatus read(LiveFrame& frame, double timeout_s) override {
    std::unique_lock lock(slot_->mutex);
    slot_->changed.wait_for(lock, std::chrono::duration<double>(std::max(0.0, timeout_s)),
                            [&] { return !slot_->queue.empty() || slot_->ended; });
    if (slot_->queue.pop(frame)) return ReadStatus::kFrame;
    return slot_->ended ? ReadStatus::kEnded : ReadStatus::kTimeout;
  }

  void stop() override {
    slot_->stop_requested = true;
    // Without a running event thread nobody else would end the stream.
    if (!context_->events.joinable() || context_->quit) Context::end(*slot_, "stopped");
  }

  std::string end_reason() const override {
    std::lock_guard lock(slot_->mutex);
    return slot_->end_reason;
  }
  long dropped_frames() const override {
    std::lock_guard lock(slot_->mutex);
    return slot_->dropped;
  }

 private:
  std::shared_ptr<Context> context_;
  Slot* slot_;
};

freenect_context* init_context() {
  freenect_context* context = nullptr;
  if (freenect_init(&context, nullptr) < 0 || !context) throw IoError("libfreenect: cannot initialise (no USB access?)");
  freenect_set_log_callback(context, log_to_string);
  freenect_set_log_level(context, FREENECT_LOG_ERROR);
  freenect_select_subdevices(context, FREENECT_DEVICE_CAMERA);  // no motor, no audio (which needs firmware)
  return context;
}

std::vector<KinectDevice> devices_of(freenect_context* context) {
  std::vector<KinectDevice> devices;
  const int count = freenect_num_devices(context);
  for (int i = 0; i < count; ++i) devices.push_back({.index = i, .serial = ""});
  const auto list = optional_symbol<ListAttributesFn>("freenect_list_device_attributes");
  const auto free_list = optional_symbol<FreeAttributesFn>("freenect_free_device_attributes");
  if (list && free_list) {
    freenect_device_attributes* attributes = nullptr;
    if (list(context, &attributes) >= 0) {
      int i = 0;
      for (freenect_device_attributes* a = attributes; a && i < count; a = a->next, ++i) {
        devices[i].serial = a->camera_serial ? a->camera_serial : "";
      }
      free_list(attributes);
    }
  }
  return devices;
}

// The devices a --devices selection names, in its order.
std::vector<KinectDevice> select_devices(const std::string& selection, const std::vector<KinectDevice>& devices) {
  if (devices.empty()) {
    throw IoError("--devices " + selection + ": no Kinect v1 found (plugged in, powered, and may this user open it? README.md, \"Live capture\")");
  }
  if (selection == "all") return devices;
  std::vector<KinectDevice> chosen;
  std::set<int> seen;
  size_t start = 0;
  while (start <= selection.size()) {
    size_t end = selection.find(',', start);
    if (end == std::string::npos) end = selection.size();
    const std::string token = selection.substr(start, end - start);
    start = end + 1;
    if (token.empty()) throw InvalidInput("--devices: \"" + selection + "\": an empty entry (expected all, INDEX,... or SERIAL,...)");
    const bool is_index = token.size() <= 3 && std::all_of(token.begin(), token.end(), [](char ch) { return ch >= '0' && ch <= '9'; });
    int found = -1;
    if (is_index) {
      const int index = std::stoi(token);
      if (index >= static_cast<int>(devices.size())) {
        throw InvalidInput("--devices: index " + token + ": only " + std::to_string(devices.size()) + " Kinect v1 found (indices 0.." +
                           std::to_string(devices.size() - 1) + ")");
      }
      found = index;
    } else {
      for (const KinectDevice& d : devices) {
        if (d.serial == token) found = d.index;
      }
      if (found < 0) {
        const bool listed = std::any_of(devices.begin(), devices.end(), [](const KinectDevice& d) { return !d.serial.empty(); });
        throw InvalidInput("--devices: serial " + token + (listed ? ": no such Kinect v1 (zipfusion record --list-devices shows them)"
                                                                  : ": this libfreenect cannot list serials (fakenect?): select by index"));
      }
    }
    if (!seen.insert(found).second) throw InvalidInput("--devices: device " + token + " is selected twice");
    chosen.push_back(devices[found]);
  }
  return chosen;
}

CameraModel model_of(Slot& slot, KinectDepthFormat format) {
  CameraModel model = kinect_v1_default_model("cam");
  if (format == KinectDepthFormat::kRegistered) {
    model.depth_intrinsics = *model.color_intrinsics;
    model.color_from_depth = Rigid3d::Identity();
    return model;
  }
  if (format == KinectDepthFormat::kRaw) return model;
  const auto copy = optional_symbol<CopyRegistrationFn>("freenect_copy_registration");
  const auto destroy = optional_symbol<DestroyRegistrationFn>("freenect_destroy_registration");
  if (!copy || !destroy) return model;
  freenect_registration registration = copy(slot.device);
  const freenect_zero_plane_info& zero_plane = registration.zero_plane_info;
  if (zero_plane.reference_distance > 0 && zero_plane.reference_pixel_size > 0) {
    // libfreenect's freenect_camera_to_world: the zero-plane pixel is for 1280×1024, the 640×480
    // stream halves it; the optical axis at pixel (320, 240).
    const double f = zero_plane.reference_distance / (2.0 * zero_plane.reference_pixel_size);
    model.depth_intrinsics = {.width = 640, .height = 480, .fx = f, .fy = f, .cx = 320, .cy = 240};
  }
  if (zero_plane.dcmos_rcmos_dist > 0 && zero_plane.dcmos_rcmos_dist < 10) {
    model.color_from_depth.translation() = Eigen::Vector3d(-zero_plane.dcmos_rcmos_dist / 100.0, 0, 0);  // cm → m
  }
  destroy(&registration);
  return model;
}

// Under fakenect (FAKENECT_PATH set): a dump fakenect would die on part-way (a listed file
// missing or short, as a crash of fakenect-record leaves it) is replayed up to that file only, so
// the stream ends cleanly there.
void limit_fakenect_replay(Context& context) {
  const char* path = std::getenv("FAKENECT_PATH");
  if (!path || !*path) return;
  const std::vector<FakenectIndexEntry> entries = read_fakenect_index(path);  // throws IoError naming INDEX.txt
  std::string problem;
  const size_t playable = fakenect_playable_entries(path, entries, problem);
  if (playable == entries.size()) return;
  context.event_calls_left = static_cast<long>(playable);
  context.event_limit_reason = "the fakenect recording ends at INDEX.txt line " + std::to_string(playable + 1) + " (" + problem + ")";
}

}  // namespace

void KinectOptions::validate() const {
  if (max_queued_frames < 1 || max_queued_frames > 10000) throw InvalidInput("kinect.max_queued_frames: must be in [1, 10000]");
  if (!(stall_timeout_s > 0 && stall_timeout_s <= 600)) throw InvalidInput("kinect.stall_timeout_s: must be in (0, 600] seconds");
  if (!(start_timeout_s > 0 && start_timeout_s <= 600)) throw InvalidInput("kinect.start_timeout_s: must be in (0, 600] seconds");
  if (!(max_color_age_s >= 0 && max_color_age_s < 10)) throw InvalidInput("kinect.max_color_age_s: must be in [0, 10) seconds");
}

std::vector<KinectDevice> list_kinect_devices() {
  freenect_context* context = init_context();
  std::vector<KinectDevice> devices = devices_of(context);
  freenect_shutdown(context);
  return devices;
}

std::vector<std::unique_ptr<LiveCamera>> open_kinect_cameras(const std::string& selection, const KinectOptions& options) {
  options.validate();
  KinectDepthFormat format = options.depth_format;
  const bool registers = library_registers_depth();
  if (format == KinectDepthFormat::kAuto) format = registers ? KinectDepthFormat::kMillimetres : KinectDepthFormat::kRaw;
  if (format != KinectDepthFormat::kRaw && !registers) {
    // fakenect asserts (aborts) on any depth mode but 11-bit: never ask it for one.
    throw InvalidInput("--depth-format: this libfreenect delivers only raw 11-bit depth (fakenect): use raw or auto");
  }
  auto context = std::make_shared<Context>();
  context->options = options;
  if (!registers) limit_fakenect_replay(*context);
  context->context = init_context();
  const std::vector<KinectDevice> chosen = select_devices(selection, devices_of(context->context));
  const freenect_depth_format depth_format = format == KinectDepthFormat::kRaw          ? FREENECT_DEPTH_11BIT
                                             : format == KinectDepthFormat::kRegistered ? FREENECT_DEPTH_REGISTERED
                                                                                         : FREENECT_DEPTH_MM;
  const freenect_frame_mode depth_mode = freenect_find_depth_mode(FREENECT_RESOLUTION_MEDIUM, depth_format);
  const freenect_frame_mode video_mode = freenect_find_video_mode(FREENECT_RESOLUTION_MEDIUM, FREENECT_VIDEO_RGB);
  if (!depth_mode.is_valid || !video_mode.is_valid || depth_mode.width != video_mode.width || depth_mode.height != video_mode.height) {
    throw IoError("libfreenect: no 640x480 depth and RGB mode");
  }
  context->fps = depth_mode.framerate > 0 ? depth_mode.framerate : 30;
  for (size_t i = 0; i < chosen.size(); ++i) {
      auto slot = std::make_unique<Slot>(options.max_queued_frames);
      slot->index = chosen[i].index;
      slot->serial = chosen[i].serial;
      slot->raw = format == KinectDepthFormat::kRaw;
      slot->max_color_age_s = options.max_color_age_s;
      slot->width = depth_mode.width;
      slot->height = depth_mode.height;
      const std::string what = "Kinect v1 #" + std::to_string(slot->index);
      const int opened = slot->serial.empty() ? freenect_open_device(context->context, &slot->device, slot->index)
                                              : freenect_open_device_by_camera_serial(context->context, &slot->device, slot->serial.c_str());
      if (opened < 0 || !slot->device) {
        slot->device = nullptr;
        throw IoError(what + ": cannot open (in use by another program, or no permission: README.md, udev rules)");
      }
      freenect_set_user(slot->device, slot.get());
      if (freenect_set_depth_mode(slot->device, depth_mode) < 0 || freenect_set_video_mode(slot->device, video_mode) < 0) {
        context->slots.push_back(std::move(slot));
        throw IoError(what + ": cannot set the 640x480 depth and RGB modes");
      }
      freenect_set_depth_callback(slot->device, &Context::on_depth);
      freenect_set_video_callback(slot->device, &Context::on_video);
      const bool started = freenect_start_depth(slot->device) >= 0 && freenect_start_video(slot->device) >= 0;
      slot->started = true;
      slot->opened_s = now_s();
      context->slots.push_back(std::move(slot));
      if (!started) throw IoError(what + ": cannot start streaming (USB bandwidth? one Kinect per USB controller: README.md)");
      Slot& s = *context->slots.back();
      s.model = model_of(s, format);
      s.model.name = "cam" + std::to_string(i);
    }
  context->events = std::thread([c = context.get()] { c->run(); });
  std::vector<std::unique_ptr<LiveCamera>> cameras;
  for (auto& slot : context->slots) cameras.push_back(std::make_unique<KinectCamera>(context, slot.get()));
  return cameras;
}

}  // namespace zipfusion
