#include <iostream>

#include "Commands.h"
#include "Common.h"

namespace kestrel::cli {

void addValidateCommand(CLI::App& app, Action& action) {
    auto* cmd = app.add_subcommand("validate", "Check a graph file and report every problem found");
    auto graph = std::make_shared<std::string>();
    cmd->add_option("GRAPH", *graph, "Graph JSON file")->required();
    cmd->callback([&action, graph] {
        action = [graph]() -> int {
          GraphDesc g;
          try {
            auto plugins = loadPlugins();
            g = loadGraphFile(*graph);
            CompileOptions opt;
            opt.validateOnly = true;
            auto compiled = compileGraph(g, plugins->registry, opt);
            std::cout << *graph << ": ok (" << g.passes.size() << " passes, " << g.edges.size()
                      << " edges)\n";
            return 0;
          } catch (const GraphError& e) {
            printGraphError(e, &g);
            return 2;
          } catch (const Error& e) {
            std::cerr << "error: " << e.what() << "\n";
            return 2;
          }
        };
    });
}

}  // namespace kestrel::cli
