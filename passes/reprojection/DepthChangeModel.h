#pragma once
// The depth a static surface had last frame, predicted from this frame's depth: what the
// reprojection's depth test compares last frame's depth with when only motion vectors are given.
//
// A pinhole camera that moved by a rigid transform (R, t) sees a static point at planar depth z
// and normalised screen position (u, v) at last frame's planar depth
//   z_prev = r3 . (z u', z v', z) + t_z = z (a u + b v + c) + d,
// r3 the last row of R and u', v' affine in u, v (tangent-space coordinates). Comparing z_prev
// with z itself (the identity a = b = d = 0, c = 1) rejects every surface facing a camera that
// dollies by more than the test's tolerance per frame, and the tolerance shrinks with resolution.
// The four coefficients are fitted per frame to the motion vectors' own correspondences.
#include <cstdint>

namespace kestrel {

struct DepthChangeModel {
    float a = 0.f, b = 0.f, c = 1.f, d = 0.f;
    /// Normalised screen coordinates: u = (x + 0.5 - w/2) / max(w, h), v likewise with y.
    float uScale = 1.f, uOffset = 0.f, vOffset = 0.f;

    bool isIdentity() const { return a == 0.f && b == 0.f && c == 1.f && d == 0.f; }
    float u(int x) const { return (float(x) + uOffset) * uScale; }
    float v(int y) const { return (float(y) + vOffset) * uScale; }
    /// b v + c of row y: the part of the prediction every pixel of a row shares.
    float rowTerm(int y) const { return b * v(y) + c; }
    /// Last frame's predicted depth of depth z at pixel x of a row with rowTerm r.
    float predict(float z, int x, float r) const { return z * (a * u(x) + r) + d; }
};

/// One frame's correspondences: this frame's depth, motion to the previous frame (pixels) and
/// object ids, last frame's depth and ids (ids may be null), and the depth test's parameters.
struct DepthChangeInputs {
    int width = 0, height = 0;
    const float* depth = nullptr;
    const float* motionX = nullptr;
    const float* motionY = nullptr;
    const int32_t* ids = nullptr;
    const float* prevDepth = nullptr;
    const int32_t* prevIds = nullptr;
    float depthThreshold = 10.f;  ///< the test: |z_prev - zRef| <= threshold * tolerance
    float depthStep = 0.f;        ///< relative step of the stored depth (0: float)
};

/// Robust least-squares fit of the model to at most about 16k correspondences on a regular grid,
/// trimmed to those that pass the depth test. Returns the identity unless the fit makes more of
/// them pass the test than the identity does (a still camera keeps the identity exactly).
/// Deterministic, single-threaded; non-finite inputs are skipped.
DepthChangeModel fitDepthChange(const DepthChangeInputs& in);

}  // namespace kestrel
