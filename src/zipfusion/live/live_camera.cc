#include "zipfusion/live/live_camera.h"

namespace zipfusion {

CameraModel kinect_v1_default_model(const std::string& name) {
  // The Kinect v1 geometry synth renders with (docs/design.md, "Synthetic captures").
  Rigid3d color_from_depth = Rigid3d::Identity();
  color_from_depth.translation() = Eigen::Vector3d(-0.025, 0, 0);
  return {.name = name,
          .depth_intrinsics = {.width = 640, .height = 480, .fx = 580, .fy = 580, .cx = 319.5, .cy = 239.5},
          .color_intrinsics = Intrinsics{.width = 640, .height = 480, .fx = 525, .fy = 525, .cx = 319.5, .cy = 239.5},
          .color_from_depth = color_from_depth,
          .world_from_depth = Rigid3d::Identity()};
}

}  // namespace zipfusion
