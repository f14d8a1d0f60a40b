#include "DefaultScene.h"

#include "kestrel/Error.h"
#include "kestrel/Log.h"

#ifdef KESTREL_HAS_SCENEGEN
#include <scenegen/SceneGen.h>
#endif

namespace kestrel::cli {

namespace fs = std::filesystem;

fs::path ensureDefaultScene(const fs::path& dir) {
#ifdef KESTREL_HAS_SCENEGEN
    std::error_code ec;
    // A marker written last: a half-generated scene (interrupted run) is generated again.
    if (fs::exists(dir / "complete", ec)) return dir;
    scenegen::SceneOptions opt;
    opt.width = 320;
    opt.height = 180;
    opt.frames = 16;
    opt.firstFrame = 1;
    opt.referenceSpp = 64;  // 256 spp would take ~25 s (scenegen measured ~50 CPU-s); 64 keeps the first run short
    spdlog::info("generating the built-in scene ({}x{}, {} frames, 1 spp + {}-spp reference) in {}",
                 opt.width, opt.height, opt.frames, opt.referenceSpp, dir.string());
    fs::create_directories(dir, ec);
    if (ec) throw Error("cannot create " + dir.string() + ": " + ec.message());
    scenegen::writeSequence(opt, dir);
    std::FILE* f = std::fopen((dir / "complete").c_str(), "w");
    if (f) std::fclose(f);
    return dir;
#else
    (void)dir;
    throw Error("this build has no built-in scene generator: give --input PATTERN");
#endif
}

}  // namespace kestrel::cli
