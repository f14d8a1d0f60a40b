#pragma once
// A scratch folder for this test process under the system temp directory, removed when the
// process exits (ctest runs every test in a process of its own), so that the test command leaves
// nothing behind: generated scenes alone took ~7 MB per quality test.
#include <unistd.h>

#include <filesystem>
#include <string>
#include <system_error>

namespace testutil {

/// `<temp>/kestrel-test-<pid>`, created on first use and removed (with everything in it) at exit.
inline const std::filesystem::path& processTempDir() {
    struct Owned {
        std::filesystem::path path;
        ~Owned() {
            std::error_code ec;  // best effort: a destructor at exit must not throw
            std::filesystem::remove_all(path, ec);
        }
    };
    static const Owned dir{std::filesystem::temp_directory_path() /
                           ("kestrel-test-" + std::to_string(::getpid()))};
    std::filesystem::create_directories(dir.path);
    return dir.path;
}

}  // namespace testutil
