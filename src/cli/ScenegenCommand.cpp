// kestrel scenegen: path-trace a built-in analytic scene (1 spp + AOVs + a reference); --scene
// picks one of the zoo's named configurations, whose settings the other options override.
#include <scenegen/SceneGen.h>

#include <filesystem>
#include <iostream>
#include <sstream>

#include "Commands.h"
#include "Common.h"
#include "kestrel/Log.h"

namespace kestrel::cli {

namespace {

std::string zooHelp() {
    std::string text =
        "Named scene of the zoo (its size and settings; the other options override "
        "them):";
    for (const auto& z : scenegen::zooScenes()) text += "\n  " + z.name + ": " + z.description;
    return text;
}

/// The options given on the command line, applied over a zoo scene's own settings.
void overrideGiven(scenegen::SceneOptions& zoo, const scenegen::SceneOptions& given,
                   const CLI::App& cmd) {
    auto given_ = [&](const char* name) { return cmd.count(name) > 0; };
    if (given_("--width")) zoo.width = given.width;
    if (given_("--height")) zoo.height = given.height;
    if (given_("--frames")) zoo.frames = given.frames;
    if (given_("--first")) zoo.firstFrame = given.firstFrame;
    if (given_("--spp")) zoo.referenceSpp = given.referenceSpp;
    if (given_("--seed")) zoo.seed = given.seed;
    if (given_("--static-camera")) zoo.staticCamera = given.staticCamera;
    if (given_("--camera-cut")) zoo.cameraCutFrame = given.cameraCutFrame;
    if (given_("--light-change")) zoo.lightChangeFrame = given.lightChangeFrame;
    if (given_("--light-scale")) zoo.lightChangeScale = given.lightChangeScale;
    if (given_("--light-swing")) zoo.lightSwing = given.lightSwing;
    if (given_("--pixel-filter")) zoo.pixelFilterWidth = given.pixelFilterWidth;
    if (given_("--exposure")) zoo.exposure = given.exposure;
    zoo.threads = given.threads;
}

/// The message with "scenegen: " in front, once (the library's own messages start with it).
std::string prefixed(const std::string& what) {
    return what.rfind("scenegen: ", 0) == 0 ? what : "scenegen: " + what;
}

/// Whether `dir` does not exist, or is a folder with nothing in it. A render folder scenegen did
/// not write this time is the user's: scenegen does not replace its frames unless told to.
bool isEmptyOrAbsent(const std::string& dir) {
    std::error_code ec;
    if (!std::filesystem::exists(dir, ec)) return true;
    return std::filesystem::is_directory(dir, ec) && std::filesystem::is_empty(dir, ec);
}

}  // namespace

void addScenegenCommand(CLI::App& app, Action& action) {
    auto* cmd = app.add_subcommand(
        "scenegen", "Path-trace a built-in scene: 1-spp frames with every AOV and a reference");
    struct Opts {
        scenegen::SceneOptions scene;
        std::string sceneName;
        std::string layout = "canonical";
        std::string omit;
        std::string out;
        bool force = false;
    };
    auto o = std::make_shared<Opts>();
    std::vector<std::string> names;
    for (const auto& z : scenegen::zooScenes()) names.push_back(z.name);
    cmd->add_option("--out", o->out, "Output folder (noisy/ and ref/ inside)")->required();
    cmd->add_option("--scene", o->sceneName, zooHelp())->check(CLI::IsMember(names));
    cmd->add_option("--width", o->scene.width, "Width in pixels")->check(CLI::Range(1, 16384));
    cmd->add_option("--height", o->scene.height, "Height in pixels")->check(CLI::Range(1, 16384));
    cmd->add_option("--frames", o->scene.frames, "Number of frames")->check(CLI::Range(1, 100000));
    cmd->add_option("--first", o->scene.firstFrame, "First frame number");
    cmd->add_option("--spp", o->scene.referenceSpp, "Samples per pixel of the reference")
        ->check(CLI::Range(1, 1 << 20));
    cmd->add_option("--seed", o->scene.seed, "Random seed");
    cmd->add_option("--layout", o->layout, "canonical or games202")
        ->check(CLI::IsMember({"canonical", "games202"}));
    cmd->add_option("--omit", o->omit,
                    "AOVs to leave out, comma-separated (albedo,emission,motion,...)");
    cmd->add_flag("--static-camera", o->scene.staticCamera, "Keep the camera still");
    cmd->add_option("--camera-cut", o->scene.cameraCutFrame, "Frame at which the camera jumps");
    cmd->add_option("--light-change", o->scene.lightChangeFrame,
                    "Street scenes: frame from which the sun and the lamp shine at --light-scale "
                    "of their strength (the sky unchanged)");
    cmd->add_option("--light-scale", o->scene.lightChangeScale,
                    "Street scenes: the lights' strength from --light-change on (default 0.2)")
        ->check(CLI::Range(0.0, 1e6));
    cmd->add_option("--light-swing", o->scene.lightSwing,
                    "Room: the ceiling light swings along x by up to this many metres (0: still)")
        ->check(CLI::Range(0.0, 1.3));
    cmd->add_option("--pixel-filter", o->scene.pixelFilterWidth,
                    "Blackman-Harris pixel filter width in pixels (0: pixel centres; street "
                    "scenes only; Blender's default is 1.5)")
        ->check(CLI::Range(0.0, 8.0));
    cmd->add_option("--exposure", o->scene.exposure,
                    "Scale of the radiance (every light AOV and the reference): renders come in "
                    "their own units; in (0, 1e9]");
    cmd->add_option("--threads", o->scene.threads, "Threads (default: all cores)");
    cmd->add_flag("--force", o->force,
                  "Write into an --out folder that is not empty (its frames are replaced)");
    cmd->callback([&action, o, cmd] {
        if (!o->sceneName.empty()) {
            scenegen::SceneOptions zoo = scenegen::zooScene(o->sceneName).options;
            overrideGiven(zoo, o->scene, *cmd);
            o->scene = zoo;
        }
        action = [o]() -> int {
            o->scene.layout = o->layout == "games202" ? scenegen::SceneOptions::Layout::Games202
                                                      : scenegen::SceneOptions::Layout::Canonical;
            std::stringstream ss(o->omit);
            for (std::string item; std::getline(ss, item, ',');)
                if (!item.empty()) o->scene.omit.insert(item);
            if (!o->force && !isEmptyOrAbsent(o->out)) {
                std::cerr << "error: scenegen --out " << o->out
                          << ": the folder is not empty (a render?): its frames would be "
                             "replaced; give a new folder, or --force\n";
                return 2;
            }
            try {
                auto stats = scenegen::writeSequence(o->scene, o->out, [](int done, int total) {
                    spdlog::debug("scenegen: frame {}/{}", done, total);
                });
                spdlog::info("scenegen: {} frames ({} files) in {} in {:.2f} s",
                             stats.framesWritten, stats.filesWritten, o->out, stats.seconds);
            } catch (const std::invalid_argument& e) {
                std::cerr << "error: " << prefixed(e.what()) << "\n";
                return 2;
            } catch (const std::exception& e) {
                std::cerr << "error: " << prefixed(e.what()) << "\n";
                return 1;
            }
            return 0;
        };
    });
}

}  // namespace kestrel::cli
