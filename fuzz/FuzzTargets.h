#pragma once
// The fuzz targets' logic, shared by the libFuzzer binaries (fuzz/*_fuzzer.cpp) and the corpus
// replay test (tests/stability/fuzz_replay_test.cpp), so every input in fuzz/corpus/ -- seeds and
// inputs that once crashed -- runs in the ordinary test suite too.
//
// Contract: any input may be rejected with a kestrel::Error (the documented way to refuse bad
// data); anything else -- a crash, a sanitizer report, another exception type escaping, a hang --
// is a finding.
#include <cstddef>
#include <cstdint>
#include <filesystem>

namespace kestrel {
class Registry;
}

namespace kestrel::fuzz {

/// Graph JSON: parseGraph, then compileGraph(validateOnly) against `registry`, then the
/// compiled graph's DOT and provenance dumps. Returns true if the graph compiled.
bool graphTarget(const uint8_t* data, size_t size, const Registry& registry);

/// EXR bytes: written to `scratchDir`/fuzz.0001.exr, then read by the ExrLoader pass (layout
/// auto-detected, every output it offers consumed) through kestrel::testing::PassHarness.
/// Returns true if the frame was read.
bool exrTarget(const uint8_t* data, size_t size, const std::filesystem::path& scratchDir);

}  // namespace kestrel::fuzz
