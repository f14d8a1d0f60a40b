#pragma once
// Matrices of the GAMES202 homework-5 layout (../shared/data/README.md, `games202-box`).
#include "scenegen/SceneGen.h"

namespace kestrel::scenegen {

/// World-to-camera with z_cam forward and positive (x right, y up): the OpenGL view with its
/// z row negated.
Mat4 games202WorldToCamera(const FrameAovs& f);
/// World-to-screen = viewport x projection x view: after the divide, pixel coordinates (x right,
/// y down, centres at +0.5); w = z_cam; z = (z_cam - near) / z_cam with near = 0.01 like the
/// homework's files.
Mat4 games202WorldToScreen(const FrameAovs& f);
/// The .mat file: int32 N, then N object-to-world, world-to-camera, world-to-screen (float32,
/// row-major), little-endian.
std::vector<char> games202MatrixFile(const FrameAovs& f);

}  // namespace kestrel::scenegen
