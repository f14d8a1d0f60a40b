#pragma once
// Previews through the user's colour management: the OpenColorIO config that $OCIO names (a
// studio's config, Blender's with Filmic or AgX), from its scene_linear role to its default
// display and view, as the user's viewer shows renders. Without $OCIO the previews keep the
// built-in tone curve and sRGB (display/ToneMap.h).
#include <cstddef>
#include <memory>
#include <string>

namespace kestrel::exr {

class OcioView {
public:
    /// The view of the config $OCIO names; nullptr when $OCIO is unset or empty, or (with a
    /// warning) when this build has no OpenColorIO. Throws Error naming $OCIO and the file when
    /// the config does not load or has no display.
    static std::unique_ptr<OcioView> fromEnvironment();
    virtual ~OcioView() = default;
    /// Scene-linear RGB triples (interleaved, `pixels` of them) to display values, in place.
    virtual void apply(float* rgb, size_t pixels) const = 0;
    /// "config FILE, display D, view V" for the log.
    virtual std::string describe() const = 0;
};

}  // namespace kestrel::exr
