#include <graphdot/GraphDot.h>

#include <fstream>
#include <iostream>

#include "Commands.h"
#include "Common.h"
#include "OutputSafety.h"
#include "kestrel/Log.h"
#include "kestrel/SequenceRunner.h"

namespace kestrel::cli {

void addGraphCommand(CLI::App& app, Action& action) {
    auto* cmd = app.add_subcommand(
        "graph", "Compile a graph for a scene and show the result (Graphviz DOT)");
    auto o = std::make_shared<GraphOptions>();
    auto dot = std::make_shared<bool>(false);
    auto all = std::make_shared<bool>(false);
    auto outFile = std::make_shared<std::string>();
    cmd->add_option("GRAPH", o->graph, "Graph JSON file (default: the shipped svgf.json)");
    cmd->add_flag("--dot", *dot,
                  "Write Graphviz DOT of the compiled graph: one box per group instance, the "
                  "passes this scene leaves out hidden");
    cmd->add_flag("--all", *all,
                  "With --dot: every pass, group instances as clusters, left-out passes dashed "
                  "with their reasons");
    cmd->add_option("-o,--out", *outFile, "Write to this file instead of standard output");
    cmd->add_option("--input", o->inputs, "Input pattern (PATTERN or name=PATTERN)")
        ->expected(1)
        ->multi_option_policy(CLI::MultiOptionPolicy::TakeAll);
    cmd->add_option("--set", o->sets, "Override a parameter: pass.param=value")
        ->expected(1)
        ->multi_option_policy(CLI::MultiOptionPolicy::TakeAll);
    cmd->callback([&action, o, dot, all, outFile] {
        action = [o, dot, all, outFile]() -> int {
            std::unique_ptr<Plugins> plugins;
            std::unique_ptr<CompiledGraph> compiled;
            GraphDesc g;
            try {
                plugins = loadPlugins();
                g = prepareGraph(*o, plugins->registry);
                compiled = compileGraph(g, plugins->registry);
                refuseUnusedOverrides(*compiled, o->sets, plugins->registry);
                if (!outFile->empty()) {  // never over the graph, its includes or the frames
                    FilesRead read;
                    read.addGraph(g);
                    read.addSources(*compiled, sourceFrames(*compiled));
                    read.check(*outFile, "-o", "give another -o");
                }
            } catch (const GraphError& e) {
                printGraphError(e, &g);
                return 2;
            } catch (const Error& e) {
                std::cerr << "error: " << e.what() << "\n";
                return 2;
            }
            std::string text;
            if (*dot) {
                text = *all ? compiled->toDot() : graphdot::overviewDot(*compiled);
            } else {
                for (const auto& n : compiled->executionOrder()) text += n + "\n";
                for (const auto& p : compiled->report().pruned)
                    text += "pruned " + p.pass + ": " + p.reason + "\n";
                for (const auto& p : compiled->report().elided)
                    text += "left out " + p.pass + ": " + p.reason + "\n";
                for (const auto& f : compiled->report().fused) {
                    text += "fused";
                    for (size_t i = 0; i < f.size(); ++i) text += (i ? " + " : " ") + f[i];
                    text += "\n";
                }
            }
            if (outFile->empty()) {
                std::cout << text;
            } else {
                std::ofstream f(*outFile);
                f << text;
                if (!f) throw Error("cannot write " + *outFile);
            }
            return 0;
        };
    });
}

}  // namespace kestrel::cli
