#pragma once
//! \file
//! The depth sensor's noise, where the pipeline needs a number for it: Kinect v1's axial standard
//! deviation (the simulator draws from it, registration weighs by it, foreground extraction keeps
//! the floor's noise out of the capture volume with it).

namespace zipfusion {

//! Kinect v1 axial noise σ(z) = 1.2 mm + 1.9 mm·(z − 0.4 m)² (Nguyen, Izadi & Lovell 2012), metres,
//! at depth z metres. A plain element function (float on the per-pixel paths, double in the
//! simulator).
template <typename Real>
inline Real kinect_axial_sigma_m(Real z) {
  const Real beyond_near = z - Real(0.4);
  return Real(0.0012) + Real(0.0019) * beyond_near * beyond_near;
}

}  // namespace zipfusion
