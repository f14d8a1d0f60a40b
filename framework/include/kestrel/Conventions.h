#pragma once
// In-memory data conventions every loader produces and every pass may rely on
// (docs/canonical-layout.md, docs/layouts.md). Loaders convert each file layout to these.
#include <cstdint>

namespace kestrel {

/// Linear view-space depth (distance along the view axis, positive) of background pixels.
constexpr float kBackgroundDepth = 1e10f;
/// objectId of background pixels (no geometry).
constexpr int32_t kBackgroundId = -1;

// Canonical port names of scene data (loader outputs, pass inputs):
//   color (Float3)    noisy radiance, linear HDR
//   albedo (Float3)   surface albedo for demodulation
//   emission (Float3) emitted radiance (added back after modulation)
//   direct, indirect (Float3)   optional split of color (radiance)
//   diffuse, specular (Float3)  optional split of color (radiance) with their own albedos
//   diffuseAlbedo, specularAlbedo (Float3)
//   normal (Float3)   world-space unit shading normal, (0,0,0) on background
//   depth (Float)     linear view depth, kBackgroundDepth on background
//   position (Float3) world-space position
//   motion (Float2)   screen motion to the previous frame in pixels, x right, y DOWN: the point
//                     seen at pixel centre (i+0.5, j+0.5) was at (i+0.5+mx, j+0.5+my) in frame t-1;
//                     NaN where unknown (Reprojection: a disocclusion)
//   objectId (Int32)  object id, kBackgroundId on background

/// Scene fact a source states when its depth is quantised (stored as half): the relative step
/// of the stored depth (a decimal, "0.0009765625" = 2^-10 for half). Passes that compare depths
/// widen their tolerance by it; absent means full float precision.
inline constexpr const char* kDepthPrecisionFact = "depthPrecision";

}  // namespace kestrel
