// kestrel: compile and run render-pass graphs over image sequences.
#include <algorithm>
#include <iostream>
#include <utility>

#include "Commands.h"
#include "Common.h"
#include "kestrel/Error.h"

int main(int argc, char** argv) {
    CLI::App app{"kestrel: a node-graph render-pass framework for denoising image sequences",
                 "kestrel"};
    app.set_version_flag("--version", std::string("kestrel ") + KESTREL_VERSION);
    app.require_subcommand(0, 1);
    // Usage errors read like every other error: one "error:" line, then a hint. Set before the
    // subcommands are added: they copy it.
    app.failure_message([](const CLI::App*, const CLI::Error& e) {
        return "error: " + std::string(e.what()) + "\nRun with --help for more information.\n";
    });
    bool verbose = false;
    app.add_flag("-v,--verbose", verbose, "More detail in logs and error messages")->configurable(false);

    kestrel::cli::Action action;
    kestrel::cli::addRunCommand(app, action);
    kestrel::cli::addValidateCommand(app, action);
    kestrel::cli::addPassesCommand(app, action);
    kestrel::cli::addGraphCommand(app, action);
    kestrel::cli::addFarmCommand(app, action);
#ifdef KESTREL_HAS_SCENEGEN
    kestrel::cli::addScenegenCommand(app, action);
#endif
#ifdef KESTREL_HAS_EVAL
    kestrel::cli::addCompareCommand(app, action);
#endif
#ifdef KESTREL_HAS_BENCH
    kestrel::cli::addBenchCommand(app, action);
#endif
    app.footer("With no subcommand, `kestrel` runs graphs/svgf.json on the built-in scene.");

    // A first word that is not an option must name a subcommand ("kestrel rnu" is not a graph).
    for (int i = 1; i < argc; ++i) {
        std::string word = argv[i];
        if (!word.empty() && word[0] == '-') continue;
        const auto subs = std::as_const(app).get_subcommands([](const CLI::App*) { return true; });
        if (std::none_of(subs.begin(), subs.end(), [&](const CLI::App* s) { return s->check_name(word); })) {
            std::string names;
            for (const auto* sub : subs) names += (names.empty() ? "" : ", ") + sub->get_name();
            std::cerr << "error: unknown subcommand '" << word << "' (commands: " << names
                      << ")\nRun with --help for more information.\n";
            return 2;
        }
        break;
    }
    try {
        app.parse(argc, argv);
    } catch (const CLI::ParseError& e) {
        int code = app.exit(e);
        return code == 0 ? 0 : 2;
    }
    kestrel::cli::setupLogging(verbose || kestrel::cli::gVerbose);
    try {
        if (!action) {
            // No subcommand: the main job, SVGF on the built-in scene.
            const char* args[] = {"kestrel", "run"};
            CLI::App runApp{"kestrel run", "kestrel"};
            kestrel::cli::addRunCommand(runApp, action);
            runApp.parse(2, const_cast<char**>(args));
        }
        return action();
    } catch (const kestrel::GraphError& e) {
        kestrel::cli::printGraphError(e);
        return 2;
    } catch (const kestrel::Error& e) {
        std::cerr << "error: " << e.what() << "\n";
        return 1;
    } catch (const std::exception& e) {
        std::cerr << "error: " << e.what() << "\n";
        return 1;
    }
}
