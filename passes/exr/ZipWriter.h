#pragma once
// writeZipScanlines: the writer's counterpart of ZipScanlines. A single-part scan-line EXR with
// ZIP or ZIPS compression, its header written by OpenEXR (Imf::Header::writeTo), its chunks
// encoded as OpenEXR's ZIP compressor does (bytes split into even and odd halves, a byte-delta
// predictor, zlib format) but deflated by libdeflate on up to `threads` threads: OpenEXR 3.1's
// zlib takes ~190 ms for a 1080p half RGB frame with two threads. Any reader decodes the files
// to the same values (tests read them back through OpenEXR).
#include <OpenEXR/ImfHeader.h>

#include <functional>
#include <string>
#include <vector>

#include "Workspace.h"

namespace kestrel::exr {

/// Called after each chunk is written with the number written so far (tests inject faults).
using ZipChunkHook = std::function<void(size_t chunksWritten)>;

/// Fills `dst` with scan line `row` (0 = the data window's first) of channel `channel` (the
/// header's alphabetical order): the data window's width values of the channel's type. Called
/// from up to `threads` threads at once, each row and channel once; it may throw.
using ZipRowSource = std::function<void(size_t channel, size_t row, unsigned char* dst)>;

/// `rows` gives the pixels a chunk at a time, so no frame-sized copy is needed; chunks are encoded
/// a batch at a time (a few per thread) and written in order, so only a batch of them is held.
/// `level`: deflate level, 1 (fastest) to 12 (smallest). Throws what the stream throws on I/O
/// errors, what `rows` throws, and Error for a header it cannot write (not ZIP/ZIPS, or a
/// channel of another type). The file is closed, not flushed to disk: the caller fsyncs before
/// renaming it. `lent`: where it has two regions per thread and one per chunk of the batch,
/// each holding a chunk, the chunk buffers live there instead of in memory of their own.
void writeZipScanlines(const std::string& path, const Imf::Header& header, const ZipRowSource& rows,
                       int threads, int level, const ZipChunkHook& afterChunk = {},
                       const Workspace& lent = {});

/// The same from `planes`: one per channel of `header`, in the header's order, each the data
/// window's width x height values of the channel's type (HALF or FLOAT), row by row.
void writeZipScanlines(const std::string& path, const Imf::Header& header,
                       const std::vector<const void*>& planes, int threads, int level,
                       const ZipChunkHook& afterChunk = {}, const Workspace& lent = {});

}  // namespace kestrel::exr
