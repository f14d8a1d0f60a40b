#include "OcioView.h"

#include <cstdlib>
#include <mutex>

#include "kestrel/Error.h"
#include "kestrel/Log.h"
#include "kestrel/Plugin.h"

namespace kestrel::exr {

namespace {

using OpenFn = void* (*)(const char*, char*, size_t);
using ApplyFn = void (*)(const void*, float*, size_t);
using DescribeFn = const char* (*)(const void*);
using CloseFn = void (*)(void*);

struct Module {
    OpenFn open = nullptr;
    ApplyFn apply = nullptr;
    DescribeFn describe = nullptr;
    CloseFn close = nullptr;
    std::string why;  ///< why there is none
};

/// kestrel_ocio beside the plugin folder (<libdir>/kestrel/), opened once, on the first preview
/// with $OCIO set (OcioModule.cpp: OpenColorIO is linked there only).
const Module& ocioModule() {
    static Module module;
    static std::once_flag once;
    std::call_once(once, [] {
        const HelperModule m = openHelperModule("kestrel_ocio.so");
        if (!m.handle) {
            module.why = m.error;
            return;
        }
        module.open = reinterpret_cast<OpenFn>(m.symbol("kestrel_ocio_open"));
        module.apply = reinterpret_cast<ApplyFn>(m.symbol("kestrel_ocio_apply"));
        module.describe = reinterpret_cast<DescribeFn>(m.symbol("kestrel_ocio_describe"));
        module.close = reinterpret_cast<CloseFn>(m.symbol("kestrel_ocio_close"));
        if (!module.open || !module.apply || !module.describe || !module.close) {
            module.open = nullptr;
            module.why = m.path.string() + " lacks its entry points";
        }
    });
    return module;
}

class ModuleView final : public OcioView {
public:
    ModuleView(const Module& m, void* view) : m_(m), view_(view) {}
    ~ModuleView() override { m_.close(view_); }
    ModuleView(const ModuleView&) = delete;
    ModuleView& operator=(const ModuleView&) = delete;
    void apply(float* rgb, size_t pixels) const override { m_.apply(view_, rgb, pixels); }
    std::string describe() const override { return m_.describe(view_); }

private:
    const Module& m_;
    void* view_;
};

}  // namespace

std::unique_ptr<OcioView> OcioView::fromEnvironment() {
    const char* env = std::getenv("OCIO");
    if (!env || !*env) return nullptr;
    const Module& m = ocioModule();
    if (!m.open) {
        // $OCIO is often set for other programs: a build without OpenColorIO still runs.
        spdlog::warn(
            "$OCIO={}: this build has no OpenColorIO module ({}; install libopencolorio-dev and "
            "rebuild); previews use the built-in sRGB",
            env, m.why);
        return nullptr;
    }
    char err[512] = {0};
    void* view = m.open(env, err, sizeof err);
    if (!view)
        throw Error(std::string("$OCIO=") + env + ": cannot use the OpenColorIO config: " + err +
                    " (unset OCIO for the built-in sRGB previews)");
    return std::make_unique<ModuleView>(m, view);
}

}  // namespace kestrel::exr
