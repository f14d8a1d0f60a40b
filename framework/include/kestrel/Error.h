#pragma once
// Errors the engine and passes raise. Library code never exits the process: it throws one of
// these, and the CLI turns it into one clear line and an exit code.
#include <stdexcept>
#include <string>
#include <vector>

namespace kestrel {

/// A fatal error with a message meant for the user (names the file, pass, port or parameter).
class Error : public std::runtime_error {
public:
    using std::runtime_error::runtime_error;
};

/// A problem confined to one frame (missing or corrupt input file). With --skip-bad-frames the
/// run skips the frame and resets history; otherwise it is fatal like Error.
class FrameError : public Error {
public:
    using Error::Error;
};

/// One validation finding, pointing at the JSON location it concerns.
struct Diagnostic {
    std::string path;        ///< JSON path, e.g. "passes[3].params.alpha" (empty: whole document)
    std::string message;     ///< what was expected and what was found
    std::string label = {};  ///< what it concerns by name, e.g. "diffuse.atrous2.sigmaL" (optional)
    /// "path (label): message"
    std::string str() const {
        std::string where = label.empty() ? path : path.empty() ? label : path + " (" + label + ")";
        return where.empty() ? message : where + ": " + message;
    }
};

/// Every problem validation found in a graph, gathered and thrown once.
class GraphError : public Error {
public:
    explicit GraphError(std::vector<Diagnostic> diags);
    const std::vector<Diagnostic>& diagnostics() const { return diags_; }

private:
    std::vector<Diagnostic> diags_;
};

}  // namespace kestrel
