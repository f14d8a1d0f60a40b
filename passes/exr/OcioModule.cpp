// kestrel_ocio: the one place OpenColorIO is linked, a module that OcioView (OcioView.cpp) opens
// with dlopen only when a preview is written with $OCIO set. Linked into the EXR plugin,
// OpenColorIO and its own dependencies (yaml-cpp, expat, minizip, ...) were loaded at every start,
// by every run, previews or not.
#include <OpenColorIO/OpenColorIO.h>

#include <cstring>
#include <exception>
#include <stdexcept>
#include <string>

namespace OCIO = OCIO_NAMESPACE;

namespace {

struct View {
    OCIO::ConstCPUProcessorRcPtr cpu;
    std::string what;
};

void setError(char* err, size_t size, const std::string& what) {
    if (size == 0) return;
    std::strncpy(err, what.c_str(), size - 1);
    err[size - 1] = '\0';
}

}  // namespace

/// The config `file`'s default display and view, from its scene_linear role (else its default
/// role); null and a message in `err` when it does not load or has no display or view.
extern "C" void* kestrel_ocio_open(const char* file, char* err, size_t errSize) {
    try {
        OCIO::ConstConfigRcPtr config = OCIO::Config::CreateFromFile(file);
        const char* display = config->getDefaultDisplay();
        if (!display || !*display) throw std::runtime_error("it has no display");
        const char* view = config->getDefaultView(display);
        if (!view || !*view)
            throw std::runtime_error(std::string("display ") + display + " has no view");
        // Renders are scene-linear; a config without that role names its working space default.
        const char* source =
            config->hasRole(OCIO::ROLE_SCENE_LINEAR) ? OCIO::ROLE_SCENE_LINEAR : OCIO::ROLE_DEFAULT;
        auto* v = new View;
        v->cpu = config->getProcessor(source, display, view, OCIO::TRANSFORM_DIR_FORWARD)
                     ->getDefaultCPUProcessor();
        v->what = std::string("config ") + file + ", display " + display + ", view " + view;
        return v;
    } catch (const std::exception& e) {
        setError(err, errSize, e.what());
        return nullptr;
    }
}

/// Scene-linear RGB triples (interleaved) to display values, in place.
extern "C" void kestrel_ocio_apply(const void* view, float* rgb, size_t pixels) {
    OCIO::PackedImageDesc desc(rgb, long(pixels), 1, 3);
    static_cast<const View*>(view)->cpu->apply(desc);
}

/// "config FILE, display D, view V"; valid until kestrel_ocio_close.
extern "C" const char* kestrel_ocio_describe(const void* view) {
    return static_cast<const View*>(view)->what.c_str();
}

extern "C" void kestrel_ocio_close(void* view) {
    delete static_cast<View*>(view);
}
