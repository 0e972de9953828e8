#pragma once
//! \file
//! The Kinect v1 depth sensor model used by `synth`: it turns the true depth a camera sees into
//! the 16-bit depth map a Kinect v1 would deliver. Every effect can be switched off.
//!
//! Effects, in the order applied per pixel:
//!  1. projector shadow: no depth where the IR projector (baseline_m along +x of the depth camera)
//!     cannot see the surface;
//!  2. dropout at depth edges: pixels next to a jump larger than edge_jump_m are lost with
//!     edge_dropout_probability (the correlation window straddles two surfaces);
//!  3. small random holes (specularities, low IR return);
//!  4. axial noise σ(z) = 1.2 mm + 1.9 mm·(z − 0.4 m)² (Nguyen, Izadi & Lovell 2012);
//!  5. quantisation of the disparity f·b/z to 1/8 pixel (the Kinect's sub-pixel resolution);
//!  6. the working range [min_range_m, max_range_m].
//! Randomness is a counter-based hash of (seed, pixel, effect), so the result does not depend on
//! the order pixels are processed in, and the per-pixel functions port to CUDA as they are.

#include <cstdint>

#include "zipfusion/core/camera.h"
#include "zipfusion/core/depth_noise.h"
#include "zipfusion/core/image.h"

namespace zipfusion {

struct KinectNoiseOptions {
  bool projector_shadows = true;
  double baseline_m = 0.075;              // IR projector to IR camera, metres (Kinect v1)
  bool edge_dropout = true;
  double edge_jump_m = 0.05;              // depth jump that counts as an edge, metres
  double edge_dropout_probability = 0.6;  // chance an edge pixel is lost
  bool random_holes = true;
  double hole_seed_density = 2e-4;        // hole centres per pixel
  int hole_max_radius_px = 2;             // holes are discs of radius 0..this, pixels
  bool axial_noise = true;                // σ(z) from Nguyen et al. 2012
  bool disparity_quantization = true;
  double disparity_step_px = 0.125;       // 1/8 px sub-pixel disparity
  double min_range_m = 0.4;               // metres
  double max_range_m = 4.5;               // metres

  //! All effects off: the ideal depth, rounded to the depth unit.
  static KinectNoiseOptions none();
  void validate() const;  // throws InvalidInput naming the field
};

//! Depth step between adjacent disparity levels at z: z²·step/(f·b), metres.
inline double kinect_quantization_step_m(double z, double focal_px, double baseline_m, double step_px) {
  return z * z * step_px / (focal_px * baseline_m);
}

//! Simulates the sensor. `true_depth` is metres along the axis (infinity = nothing);
//! `projector_depth` is the true depth rendered from the projector (same intrinsics, placed
//! baseline_m along +x), used for shadows (may be empty when shadows are off).
//! Returns raw depth in units of `depth_unit_m` (0 = no measurement).
DepthImage simulate_kinect_depth(const Image<float>& true_depth, const Image<float>& projector_depth, const Intrinsics& k,
                                 const KinectNoiseOptions& options, double depth_unit_m, std::uint64_t seed);

//! Counter-based random numbers: uniform in [0, 1) and standard normal, a pure function of
//! (seed, index, stream).
double hash_uniform(std::uint64_t seed, std::uint64_t index, std::uint64_t stream);
double hash_normal(std::uint64_t seed, std::uint64_t index, std::uint64_t stream);

}  // namespace zipfusion
