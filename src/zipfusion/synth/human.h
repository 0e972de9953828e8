#pragma once
//! \file
//! The built-in synthetic subject: an articulated human figure made of smooth closed primitives
//! (tapered capsules for limbs, neck and waist; ellipsoids for head, chest, pelvis, hands and
//! feet) that walks along a circle while waving its right hand. Its colours form a pattern that
//! makes colour mapping checkable by eye and by numbers (HumanPalette).

#include "zipfusion/core/image.h"
#include "zipfusion/core/mesh.h"

namespace zipfusion {

//! Shape and motion of the synthetic subject. validate() once where the options enter (CLI,
//! config); make_human asserts them.
struct HumanOptions {
  double height_m = 1.72;          // top of head above the floor, standing straight; in [0.3, 3]
  double walk_radius_m = 0.3;      // walks along a circle of this radius around the origin (0 = walks in place)
  double walk_period_s = 10.0;     // time for one lap of that circle (> 0)
  double stride_period_s = 1.1;    // one full gait cycle (two steps) (> 0)
  double wave_period_s = 1.2;      // right forearm waving back and forth (> 0)
  int segments = 32;               // tessellation around each primitive; rings scale with it (make_human); [8, 1024]

  //! Throws InvalidInput naming the field, e.g. "human.segments: must be >= 8".
  void validate() const;
};

//! Vertex colours of the figure. All parts are coloured from their rest-pose coordinates, so the
//! pattern moves with the body.
struct HumanPalette {
  Rgb8 skin{224, 172, 138};           // face, neck, forearms, hands
  Rgb8 hair{92, 56, 30};              // top and back of the head
  Rgb8 eye{16, 16, 22};               // two eyes on the front of the head (the face marker)
  Rgb8 mouth{178, 52, 58};            // a short band below the eyes
  Rgb8 shirt_a{200, 32, 44};          // shirt (waist, chest, shoulders, upper arms): horizontal stripes
  Rgb8 shirt_b{236, 236, 226};        //   alternating a/b, each kHumanStripeWidth tall
  Rgb8 trousers{38, 62, 150};         // pelvis, thighs, shins
  Rgb8 trouser_stripe{242, 200, 36};  // one vertical stripe down the outer side of each leg
  Rgb8 shoe{34, 30, 30};              // feet
};
inline constexpr HumanPalette kHumanPalette{};

//! Height of one shirt stripe for the 1.72 m figure, metres (it scales with height_m). Stripe k
//! covers rest-pose heights [k, k + 1) · width above the floor; even k are shirt_a.
inline constexpr double kHumanStripeWidth = 0.06;

//! The figure at time t (seconds): a coloured triangle mesh in world coordinates (metres, z up,
//! floor at z = 0), outward-facing counter-clockwise triangles.
//!
//! - Parts (18), in this order: pelvis, waist, chest, shoulder girdle, neck, head, upper arms,
//!   forearms, hands, thighs, shins, feet (left before right in each pair). Each is its own
//!   closed, watertight, consistently oriented lathed surface with pole vertices at its ends (no
//!   degenerate triangles); parts overlap at the joints. The vertices and triangles of a part are
//!   contiguous.
//! - Proportions of an adult scaled by height_m / 1.72: shoulder joints 0.36 m apart, 0.45 m
//!   across the deltoids; radii thigh 7.5 → 5 cm, shin 5 → 3.5 cm, upper arm 4.5 → 3.7 cm,
//!   forearm 3.7 → 2.8 cm. Standing straight (at mid-stance, t = k · stride_period_s / 2) the top
//!   of the head is at height_m (within 1 mm).
//! - Motion: the pelvis moves counter-clockwise along the circle of walk_radius_m around the
//!   origin, facing its tangent (with walk_radius_m = 0 it treads and turns on the spot); at t = 0
//!   it is at (walk_radius_m, 0) facing +y, the left leg in mid-swing. Gait at stride_period_s:
//!   hips flex ±25°, knees 0–55° in swing, feet stay level, pelvis and chest counter-rotate, the
//!   left arm swings ±20° against the left leg. The vertical bob follows from the legs (the lower
//!   sole rests on the floor; 7.5 cm · height_m / 1.72 peak to peak, the straight-legged double
//!   support at ±25°), and the lowest vertex is then shifted to z = 0 exactly every frame. The
//!   right arm is raised (abducted 110°, 15° forward) and its forearm waves ±30° about 70° of
//!   elbow flexion, in the frontal plane, palm forward, at wave_period_s; the hand reaches up to
//!   about 1.12 · height_m. The gait is not matched to the travel speed (the feet slide): this is a
//!   capture subject, not an animation.
//! - Tessellation: a vertex spacing of about 0.6 m · (height_m / 1.72) / segments along and
//!   around each primitive (1.9 cm at 32; 1.6 cm on the trunk to resolve the stripes, 0.85 cm on
//!   the head to resolve the eyes), with between segments/2 and 2·segments vertices around. At
//!   segments = 32: 13,680 vertices and 27,288 triangles, about 0.2–0.4 ms on one core.
//! - Deterministic: the same time and options give a bitwise-identical mesh. Thread safety: a pure
//!   function; concurrent calls are safe.
//! Precondition: options.validate() passes (asserted).
TriangleMesh make_human(double time_s, const HumanOptions& options = {});

}  // namespace zipfusion
