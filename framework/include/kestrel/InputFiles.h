#pragma once
// The rules every file Kestrel reads goes through, whichever command or pass reads it
// (docs/errors.md): a regular file (a FIFO would block the read forever, a device would be read
// forever), and for JSON (graphs, includes, camera.json, farm plans, --set values) a nesting
// depth a recursive consumer survives and no key written twice.
#include <cstdint>
#include <filesystem>
#include <string>

namespace kestrel {

/// Deepest nesting of arrays and objects accepted in any JSON Kestrel reads. A graph nests about
/// six levels; 55,000 levels overflowed the stack of every recursive walk of the document.
constexpr int kMaxJsonDepth = 256;

/// Throws Error "WHAT PATH is a directory (expected X)", "WHAT PATH is not a regular file (a
/// device, pipe or socket); expected X" or "cannot read WHAT PATH: reason" unless `path` names
/// (or links to) an existing regular file. Checked before opening: opening a FIFO for reading
/// blocks until a writer comes. `expected` ("a .json file") may be empty.
void checkRegularFile(const std::filesystem::path& path, const std::string& what,
                      const std::string& expected = {});

/// checkRegularFile, then the whole file; over `maxBytes` is an Error naming the file (a file
/// can grow between the check and the read).
std::string readRegularFile(const std::filesystem::path& path, const std::string& what,
                            std::uintmax_t maxBytes, const std::string& expected = {});

/// Throws GraphError (one diagnostic: "WHERE: ...") when JSON `text` nests arrays and objects
/// deeper than kMaxJsonDepth or an object has a key twice (nlohmann keeps the last silently),
/// naming the JSON path. Syntax errors are left to the parser, which names line and column.
void checkJsonText(const std::string& text, const std::string& where);

}  // namespace kestrel
