#pragma once
// World positions from a depth image and the frame's camera, for renders without a Position
// pass: the loader's position output then lets Reprojection use its matrix path where there are
// no motion vectors.
#include <kestrel/Math.h>

#include <array>

namespace kestrel::exr {

/// Rows [y0, y1) of a W-wide image: out[c][i] = world position of pixel i, the camera-space point
/// on pixel (x + 0.5, y + 0.5)'s ray at planar depth d (z = -d) or, with rayLength, at distance d
/// from the eye. cameraToPixel maps camera space to pixel coordinates (worldToPixel times the
/// camera-to-world matrix). Background (depth <= 0, >= 1e9 or NaN) and rays the camera cannot
/// invert get (0, 0, 0), the Position pass's background.
void unprojectRows(const Mat4& cameraToPixel, const Mat4& cameraToWorld, const float* depth,
                   bool rayLength, std::array<float*, 3> out, int W, int y0, int y1);

/// Rows [y0, y1) of world-space unit normals reconstructed from world positions (unprojectRows'
/// output, the whole W x H image) for renders with no normal pass: the cross product of the
/// position differences to the horizontal and the vertical neighbour whose depth is closer to the
/// pixel's (one-sided, so a depth edge does not tilt the surface on either side of it), turned
/// towards the eye. Geometric normals: a shading normal's bump and smoothing are not recovered.
/// Where a pixel has no neighbour on a surface in x or in y, it faces the eye; background (0, 0,
/// 0) stays 0.
void normalsFromPositionsRows(const std::array<const float*, 3>& position, const float* depth,
                              const double eye[3], std::array<float*, 3> out, int W, int H, int y0,
                              int y1);

/// Rows [y0, y1): where depth marks the background (<= 0, >= 1e9 or NaN), the motion to the
/// previous frame of a point at infinity seen through pixel (x + 0.5, y + 0.5): its direction
/// projected by the previous frame's worldToPixel (prevWorldToPixel). Other pixels, and
/// directions behind the previous camera, keep their motion.
void skyMotionRows(const Mat4& cameraToPixel, const Mat4& cameraToWorld,
                   const Mat4& prevWorldToPixel, const float* depth, std::array<float*, 2> motion,
                   int W, int y0, int y1);

}  // namespace kestrel::exr
