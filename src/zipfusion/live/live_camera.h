#pragma once
//! \file
//! The one interface behind which every live depth camera sits (Kinect v1 through libfreenect,
//! a replayed fakenect dump; later RealSense, Azure Kinect, Orbbec: README.md, "Adding a camera
//! family"). A LiveCamera delivers timestamped frames: depth in millimetres along the optical axis
//! (uint16, 0 = no measurement) and, when it has one, colour; its CameraModel gives intrinsics and
//! color_from_depth (world_from_depth is identity: world poses come from a calibration).
//!
//! Clock: `time_s` of every camera of one rig is on one clock, so frames can be grouped across
//! cameras by it (live devices: the host's steady clock when the frame arrived; replays: the
//! recording's clock). A class because the stream's state lives across calls.
//!
//! Thread safety: read() is called from one thread at a time; stop() may be called from any
//! thread, also while read() waits.

#include <cstdint>
#include <string>

#include "zipfusion/core/image.h"
#include "zipfusion/io/rig.h"

namespace zipfusion {

//! One frame of one camera.
struct LiveFrame {
  double time_s = 0;                 // seconds on the rig's common clock (see the file comment)
  std::uint32_t device_timestamp = 0;  // the device's own frame counter/clock (libfreenect's timestamp), as delivered
  DepthImage depth;                  // millimetres along the optical axis, 0 = no measurement
  bool has_color = false;
  ColorImage color;                  // RGB, the colour camera's image nearest in time to the depth (by the device's clock where it stamps both)

  //! Whether the frame holds image memory that a later frame can be written into (a frame moved
  //! from holds none).
  bool holds_images() const { return depth.data.capacity() > 0 || color.data.capacity() > 0; }
};

enum class ReadStatus {
  kFrame,    // a frame was delivered
  kTimeout,  // nothing within the timeout; the stream goes on
  kEnded,    // the stream is over (device unplugged, recording at its end, stop()); end_reason() says why
};

class LiveCamera {
 public:
  virtual ~LiveCamera() = default;

  //! Name (the capture's camera folder), depth/colour intrinsics and color_from_depth.
  virtual const CameraModel& model() const = 0;
  //! What the camera is, for messages: "Kinect v1 #0 (serial A00364A11700045A)".
  virtual std::string description() const = 0;
  //! Nominal frames per second.
  virtual double fps() const = 0;

  //! Waits up to timeout_s (seconds, ≥ 0) for the next frame. After kEnded every call returns
  //! kEnded. Frames already queued when the stream ends are delivered first. `frame` comes in
  //! holding an earlier frame (its images to be reused): on kFrame every field is written, or the
  //! whole frame swapped with a queued one (LiveFrameQueue) — time_s, device_timestamp, depth,
  //! has_color (false where there is no colour: the old colour is still there) and, with
  //! has_color, color. The camera may keep `frame`'s old images to fill later, so a reader that
  //! hands back the frames it is done with gets a steady stream without allocating.
  virtual ReadStatus read(LiveFrame& frame, double timeout_s) = 0;
  //! Ends the stream: no new frames are taken; frames already queued are still delivered.
  virtual void stop() = 0;

  //! Why the stream ended ("stopped", "end of the recording", "no frame for 2 s: unplugged?");
  //! empty while it runs.
  virtual std::string end_reason() const = 0;
  //! Frames the camera delivered to its queue but had to discard because the reader fell behind
  //! (queue full); they were never reported as captured.
  virtual long dropped_frames() const = 0;
};

//! A Kinect v1 camera model for a 640×480 depth and colour stream without registration data from
//! the device (as under fakenect): depth f = 580 px, colour f = 525 px, principal points at the
//! image centre, the colour camera 2.5 cm along the depth camera's +x: the values `synth` uses.
CameraModel kinect_v1_default_model(const std::string& name);

}  // namespace zipfusion
