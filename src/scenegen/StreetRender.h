#pragma once
// renderFrame / renderReference of the street kinds (options already checked).
#include <vector>

#include "Street.h"

namespace kestrel::scenegen {

FrameAovs renderStreetFrame(const SceneOptions& options, int frame);
std::vector<float> renderStreetReference(const SceneOptions& options, int frame);

}  // namespace kestrel::scenegen
