#pragma once
// What `reconstruct` and `serve` share: the reconstruction's options on the command line, and
// the reconstruction of a capture they set up (the rig and its poses, --register once or in the
// background).

#include <CLI/CLI.hpp>
#include <memory>
#include <nlohmann/json.hpp>
#include <string>

#include "cli/frame_range.h"
#include "zipfusion/io/capture.h"
#include "zipfusion/pipeline/background_registration.h"
#include "zipfusion/pipeline/pipeline.h"

namespace zipfusion::cli {

struct ReconstructionArgs {
  std::string mode = "zipper";
  std::string filter = "bilateral";
  std::string ownership = "auto";  // auto, border or smoothness (ZipperOptions::ownership)
  std::string rig;  // --rig: the capture's poses from another rig.json, or the live cameras' calibration
  std::string register_mode = "auto";
  bool no_volume_crop = false;
  ReconstructOptions options;
  BackgroundRegistrationOptions background;
  // --register once: `register`'s defaults (levels 3→1, --threads cores: nothing else runs yet),
  // not the worker's 3→2 on one core; on a 3-camera rig 2° / 5 cm off the meshes came out 2.5 mm
  // from the truth, against 4.5 mm, for about a second more before the first frame.
  RegistrationOptions once_registration;
  int once_frames = 16;
};

//! --mode, --filter, --rig, --register*, --lod, the depth, filter and zipper thresholds, --threads.
void add_reconstruction_options(CLI::App* cmd, ReconstructionArgs& args);

//! Warns (`command`: warning: ...) where the volume's floor lift (--floor-noise) would apply to a
//! rig whose world does not look z-up (world_looks_z_up): the lift raises the volume's lowest-z
//! face, which is the floor's only in a z-up world. Throws InvalidInput for bad depth options.
void warn_if_world_not_z_up(const Rig& rig, const ReconstructionArgs& args, const std::string& command);

//! --mode, --filter, --ownership and --no-volume-crop into `args.options`, then every option
//! checked (InvalidInput naming it); Reconstruction does it too. For a command that must fail on
//! a bad option before it starts anything (serve binds its port first).
void apply_reconstruction_args(ReconstructionArgs& args);

//! A pose as rig.json writes it (row-major 4×4 rows), for stats.json and the stream's hello.
nlohmann::ordered_json matrix_json(const Rigid3d& pose);

//! The options as JSON (stats.json, the stream's description).
nlohmann::ordered_json options_json(const ReconstructOptions& options);

//! The reconstruction of frames seen by `rig`. With --register once the poses are refined before
//! the first frame: on up to 16 frames spread over `range` of `capture`, or on the first 16 frame
//! sets `take_live` gives (live input, when there is no capture; they are not reconstructed).
//! With background, by a worker thread as the frames go; once+background does both. auto is off
//! for one camera or where the rig marks its poses as trusted, else once+background. A rig of one
//! camera is never refined: there is nothing to register it to.
class Reconstruction {
 public:
  //! Throws InvalidInput for bad options.
  Reconstruction(const Rig& rig, const Capture* capture, ReconstructionArgs& args, const FrameRange& range,
                 const std::function<bool(FrameSet&)>& take_live = {});
  // The background registration's hook refers to this object.
  Reconstruction(const Reconstruction&) = delete;
  Reconstruction& operator=(const Reconstruction&) = delete;

  FrameReconstructor& reconstructor() { return *reconstructor_; }
  const Rig& rig() const { return start_rig_; }  // the poses reconstruction starts from (refined, with once)
  const std::string& register_mode() const { return register_mode_; }
  //! Seconds spent refining before the first frame (taking live frame sets included), 0 without.
  double refinement_s() const { return refinement_s_; }
  //! Where the poses were refined before the first frame, a line on stdout: how long it took and
  //! how far the cameras moved (the worst, relative to the first camera).
  void say_how_far_poses_moved(const std::string& command) const;
  //! The pipeline's options, with the background registration's hook when it runs.
  PipelineOptions pipeline_options();
  //! Every pose change so far: [{frame, version, world_from_depth (per camera, 4×4), refined_on_frame?}].
  const nlohmann::ordered_json& pose_updates() const { return pose_updates_; }

 private:
  Rig rig_;        // as given
  Rig start_rig_;  // refined by --register once, or as given
  std::string register_mode_;
  std::unique_ptr<FrameReconstructor> reconstructor_;
  std::unique_ptr<BackgroundRegistration> background_;
  nlohmann::ordered_json pose_updates_ = nlohmann::json::array();
  int pose_version_ = 0;   // the worker's version swapped in last
  int first_version_ = 0;  // 1 where the poses were refined before the first frame
  double refinement_s_ = 0;
};

}  // namespace zipfusion::cli
