#include "OcioView.h"

#include <cstdlib>

#include "kestrel/Error.h"
#include "kestrel/Log.h"

#ifdef KESTREL_HAS_OCIO
#include <OpenColorIO/OpenColorIO.h>
namespace OCIO = OCIO_NAMESPACE;
#endif

namespace kestrel::exr {

#ifdef KESTREL_HAS_OCIO
namespace {

class ConfigView final : public OcioView {
public:
    explicit ConfigView(const std::string& file) {
        OCIO::ConstConfigRcPtr config = OCIO::Config::CreateFromFile(file.c_str());
        const char* display = config->getDefaultDisplay();
        if (!display || !*display) throw Error("it has no display");
        const char* view = config->getDefaultView(display);
        if (!view || !*view) throw Error(std::string("display ") + display + " has no view");
        // Renders are scene-linear; a config without that role names its working space default.
        const char* source =
            config->hasRole(OCIO::ROLE_SCENE_LINEAR) ? OCIO::ROLE_SCENE_LINEAR : OCIO::ROLE_DEFAULT;
        cpu_ = config->getProcessor(source, display, view, OCIO::TRANSFORM_DIR_FORWARD)
                   ->getDefaultCPUProcessor();
        what_ = "config " + file + ", display " + display + ", view " + view;
    }
    void apply(float* rgb, size_t pixels) const override {
        OCIO::PackedImageDesc desc(rgb, long(pixels), 1, 3);
        cpu_->apply(desc);
    }
    std::string describe() const override { return what_; }

private:
    OCIO::ConstCPUProcessorRcPtr cpu_;
    std::string what_;
};

}  // namespace
#endif

std::unique_ptr<OcioView> OcioView::fromEnvironment() {
    const char* env = std::getenv("OCIO");
    if (!env || !*env) return nullptr;
#ifdef KESTREL_HAS_OCIO
    try {
        return std::make_unique<ConfigView>(env);
    } catch (const std::exception& e) {
        throw Error(std::string("$OCIO=") + env + ": cannot use the OpenColorIO config: " +
                    e.what() + " (unset OCIO for the built-in sRGB previews)");
    }
#else
    // $OCIO is often set for other programs: a build without OpenColorIO still runs.
    spdlog::warn(
        "$OCIO={}: this build has no OpenColorIO (libopencolorio-dev); previews use the "
        "built-in sRGB",
        env);
    return nullptr;
#endif
}

}  // namespace kestrel::exr
