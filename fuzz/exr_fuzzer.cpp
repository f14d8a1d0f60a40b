// libFuzzer entry: EXR bytes -> ExrLoader (layout auto-detected, all outputs read).
#include <OpenEXR/ImfThreading.h>
#include <spdlog/spdlog.h>
#include <unistd.h>

#include <filesystem>
#include <string>

#include "FuzzTargets.h"

namespace {
std::filesystem::path scratch;
}

extern "C" int LLVMFuzzerInitialize(int*, char***) {
    spdlog::set_level(spdlog::level::off);  // per-input log lines would dominate the run time
    Imf::setGlobalThreadCount(0);  // decode on the calling thread: deterministic, less noise
    scratch =
        std::filesystem::temp_directory_path() / ("kestrel-exr-fuzz-" + std::to_string(::getpid()));
    std::filesystem::create_directories(scratch);
    return 0;
}

extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, size_t size) {
    kestrel::fuzz::exrTarget(data, size, scratch);
    return 0;
}
