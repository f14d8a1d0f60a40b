#pragma once
// Subcommands of the kestrel CLI. Each lives in its own file and adds itself to the CLI11 app:
// it declares its options and sets `action` (run when the subcommand was chosen) to return the
// exit code: 0 success, 1 runtime failure, 2 usage or graph error.
#include <CLI/CLI.hpp>
#include <functional>

namespace kestrel::cli {

using Action = std::function<int()>;

void addRunCommand(CLI::App& app, Action& action);
void addValidateCommand(CLI::App& app, Action& action);
void addPassesCommand(CLI::App& app, Action& action);
void addGraphCommand(CLI::App& app, Action& action);
void addScenegenCommand(CLI::App& app, Action& action);
void addCompareCommand(CLI::App& app, Action& action);
void addBenchCommand(CLI::App& app, Action& action);
void addFarmCommand(CLI::App& app, Action& action);

}  // namespace kestrel::cli
