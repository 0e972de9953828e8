#pragma once
//! \file
//! A rig capture on disk (`zipfusion.rig/1`): a folder with rig.json, per-camera depth and colour
//! frames and optional ground truth. Opening reads and validates rig.json and the folder listing;
//! frames are decoded lazily, one at a time.
//!
//! Missing frames: a camera whose frame file is absent (a dropped frame, a camera that died
//! mid-sequence) or present but undecodable (corrupt, truncated, unreadable: a recorder killed
//! mid-write, a bad sector) degrades that frame set rather than the run:
//! load_frame() marks the camera as having no depth (or colour), and lists an undecodable file with
//! its reason (CameraFrame::unreadable). With `strict`, either is an error instead.
//! Thread safety: a Capture is immutable after open(); load_* may be called concurrently.

#include <cstdint>
#include <filesystem>
#include <initializer_list>
#include <optional>
#include <string>
#include <string_view>
#include <vector>

#include "zipfusion/core/image.h"
#include "zipfusion/io/image_io.h"
#include "zipfusion/io/rig.h"

namespace zipfusion {

struct CaptureOpenOptions {
  bool strict = false;  // a missing or undecodable depth or colour frame is an error, not a hole
};

//! One camera's images of one frame.
struct CameraFrame {
  bool has_depth = false;
  DepthImage depth;  // raw units of Rig::depth_unit_m, 0 = no measurement
  bool has_color = false;
  ColorImage color;
  //! Frame files of this camera that are present but could not be read or decoded, each as "FILE: reason"
  //! (has_depth or has_color is then false, as for a missing file); empty when opened strict,
  //! where load_camera_frame throws instead.
  std::vector<std::string> unreadable;
};

//! All cameras' images of one frame, in rig order.
struct FrameSet {
  int index = 0;
  double capture_time_ms = 0;  // when the frame set was captured, milliseconds since the Unix epoch; 0 = unknown
  std::vector<CameraFrame> cameras;
};

//! Every camera's unreadable frame files of a frame set (CameraFrame::unreadable), in rig order.
std::vector<std::string> unreadable_files(const FrameSet& set);

//! What loading one camera's frames keeps from frame set to frame set (Capture::load_camera_frame
//! into a CameraFrame): the decoder, the frame file's name, and the recorded depth of a camera
//! whose depth is undistorted.
struct CameraFrameScratch {
  ImageDecoder decoder;
  std::string path;
  DepthImage recorded;
};

//! A frame file that the rig promises but the folder lacks.
struct MissingFrame {
  int camera = 0;
  int frame = 0;
  bool color = false;  // false: the depth frame is missing
};

class Capture {
 public:
  //! Throws InvalidInput (rig.json fields, folder layout, frame_count mismatch) or IoError.
  static Capture open(const std::filesystem::path& dir, const CaptureOpenOptions& options = {});

  const std::filesystem::path& dir() const { return dir_; }
  const Rig& rig() const { return rig_; }
  int frame_count() const { return rig_.frame_count; }
  int camera_count() const { return static_cast<int>(rig_.cameras.size()); }
  const std::vector<MissingFrame>& missing_frames() const { return missing_; }

  //! ground_truth/rig.json when present (validated against the main rig: same cameras).
  const std::optional<Rig>& ground_truth_rig() const { return ground_truth_rig_; }
  //! Why a ground_truth/rig.json that is there is not used (it cannot be read, or its cameras are
  //! not rig.json's): its error, "FILE: FIELD: problem"; empty when it is used or absent. The
  //! ground truth is optional, so this does not stop opening the capture unless opened strict.
  const std::string& ground_truth_rig_problem() const { return ground_truth_rig_problem_; }
  bool has_ground_truth_meshes() const { return has_ground_truth_meshes_; }
  std::filesystem::path ground_truth_mesh_path(int frame) const;

  std::filesystem::path depth_path(int frame, int camera) const;
  //! The colour file of that frame (.jpg or .png), or an empty path when there is none.
  std::filesystem::path color_path(int frame, int camera) const;

  //! Decodes one camera's frame. A missing file leaves has_depth/has_color false; so does a file
  //! whose bytes cannot be read or decoded (CorruptFile, IoError), listed in `unreadable`; opened
  //! strict, either throws. A file that cannot even be looked at (a loop of links) throws IoError,
  //! and one whose size or bit depth does not match rig.json throws InvalidInput, strict or not. Depth whose intrinsics have distortion comes back undistorted: each
  //! pixel of a pinhole camera with the same fx, fy, cx, cy takes the depth of the recorded pixel
  //! nearest to where its ray falls (0 where that lies outside the image), so the rest of
  //! zipfusion, which back-projects depth through the pinhole model, sees straight rays.
  CameraFrame load_camera_frame(int frame, int camera) const;
  //! The same without the colour image (has_color false): for work that reads only depth.
  CameraFrame load_camera_depth(int frame, int camera) const;
  FrameSet load_frame(int frame) const;
  //! load_camera_frame (load_camera_depth without `with_color`) into `out`, whose images' buffers
  //! are reused, as are `scratch`'s: once they have grown, loading a camera's frame allocates
  //! nothing from the C++ heap (ImageDecoder says what libjpeg still does). A file left out
  //! leaves its image empty, whatever `out` held before.
  void load_camera_frame(int frame, int camera, CameraFrame& out, CameraFrameScratch& scratch, bool with_color = true) const;

  //! Throws InvalidInput ("OPTION: …") when `output` would be written among the capture's own
  //! files: the capture folder itself, a file in it, or its ground truth or a camera's folder or
  //! anything in them (meshes written there would replace the true ones, or mix with the frames).
  //! Links are resolved first. The capture's rig.json may be replaced (a refined rig written
  //! back), and a new file or folder of one's own made in the capture folder.
  void check_output_outside(const std::filesystem::path& output, std::string_view option) const;

  //! Reads the frames through another calibration of the same cameras (a `--rig`): its depth
  //! distortion undistorts the depth from now on, and rig() returns it. Throws InvalidInput when
  //! its cameras, image sizes or depth unit differ from rig.json's.
  void use_calibration(const Rig& calibrated);

 private:
  std::filesystem::path dir_;
  Rig rig_;
  CaptureOpenOptions options_;
  std::optional<Rig> ground_truth_rig_;
  std::string ground_truth_rig_problem_;
  bool has_ground_truth_meshes_ = false;
  std::vector<MissingFrame> missing_;
  enum class ColorFile : std::uint8_t { kNone, kJpg, kPng };
  static const char* extension_of(ColorFile file) { return file == ColorFile::kJpg ? ".jpg" : ".png"; }
  struct FrameFolders {
    std::string depth, color;  // each ends in a separator; the frame files' names follow
  };
  std::vector<FrameFolders> frame_folders_;  // per camera
  std::vector<std::vector<ColorFile>> color_file_;  // [camera][frame]
  std::vector<std::vector<int>> depth_undistortion_;  // depth_undistortion_maps(rig_)
};

//! For a depth camera with lens distortion: per pixel of the pinhole camera of the same fx, fy, cx,
//! cy, the index of the recorded pixel nearest to where its ray falls, or −1 outside the image.
std::vector<int> depth_undistortion_map(const Intrinsics& k);
//! Per camera of the rig, depth_undistortion_map of its depth intrinsics, empty for a camera
//! without distortion.
std::vector<std::vector<int>> depth_undistortion_maps(const Rig& rig);
//! Element function of the undistortion: pinhole pixel p of `recorded` through the map.
inline std::uint16_t undistorted_depth(const std::uint16_t* recorded, const int* source_pixel, int p) {
  return source_pixel[p] >= 0 ? recorded[source_pixel[p]] : 0;
}
//! `recorded` through camera `camera`'s map of `maps` (depth_undistortion_maps); unchanged when
//! that map is empty or missing.
DepthImage undistort_depth(DepthImage recorded, const std::vector<std::vector<int>>& maps, int camera);

//! Undistorts `recorded` through `source_pixel` (a depth_undistortion_map of camera `camera`, which
//! errors name) into `out`, whose buffer is reused.
void undistort_depth_into(const DepthImage& recorded, const std::vector<int>& source_pixel, int camera, DepthImage& out);

//! Reads frame sets of a capture into a FrameSet used again and again (the pipeline's): each camera
//! is decoded into the buffers the set already holds (Capture::load_camera_frame with a scratch
//! per camera), the cameras in parallel (parallel_for). Once the buffers have grown, reading a
//! frame set allocates nothing from the C++ heap. The capture must outlive it; not thread-safe.
class FrameSetReader {
 public:
  explicit FrameSetReader(const Capture& capture);
  //! Frame `frame` into `set` (index set, capture time 0, one CameraFrame per camera).
  void read(int frame, FrameSet& set);

 private:
  const Capture& capture_;
  std::vector<CameraFrameScratch> scratch_;  // per camera
};

//! Frame file name: 6-digit zero-padded index plus extension ("000042.png").
std::string frame_file_name(int frame, const std::string& extension);
//! The frame index of such a name with one of `extensions` (".png"), or −1 for any other name.
int frame_index_of(const std::filesystem::path& file, std::initializer_list<const char*> extensions);

}  // namespace zipfusion
