#pragma once
// The integrity of the writer's files: a checksum of every chunk stamped into the header, and
// the checks that decide whether a frame on disk is complete, intact and this run's (--resume,
// farm check).
#include <cstdint>
#include <string>

namespace kestrel::exr {

/// The header attribute holding the CRC-32 of everything after the header (the offset table
/// and every chunk) as 8 hex digits. A bit flipped inside a chunk leaves every chunk's size
/// right, and an uncompressed or stored chunk still decodes: only a checksum shows it.
constexpr char kCrcAttribute[] = "kestrel.dataCrc32";
constexpr char kCrcPlaceholder[] = "00000000";

/// Fills the placeholder of kCrcAttribute in the (closed) file `path`, whose header ends at
/// `headerEnd`, with the CRC of everything after the header. In place, the header's size and
/// every offset unchanged.
void stampChecksum(const std::string& path, uint64_t headerEnd);
/// Where the header of a single-part scan-line file ends (its offset table starts).
uint64_t headerEndOf(const std::string& path);
/// Why the file cannot be trusted as this run's output (empty: it can); see WriterIntegrity.cpp.
std::string exrProblem(const std::string& path, const std::string& provenance);
/// A PNG with its signature first and its closing IEND chunk last.
bool isCompletePng(const std::string& path);

}  // namespace kestrel::exr
