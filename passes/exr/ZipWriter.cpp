#include "ZipWriter.h"

#include <OpenEXR/ImfChannelList.h>
#include <OpenEXR/ImfStdIO.h>
#include <OpenEXR/ImfVersion.h>
#include <libdeflate.h>

#include <algorithm>
#include <atomic>
#include <cerrno>
#include <cstring>
#include <fstream>
#include <limits>
#include <memory>
#include <mutex>
#include <new>
#include <system_error>
#include <thread>

#include "kestrel/Error.h"

namespace kestrel::exr {

namespace {
/// errno as words ("No space left on device"); a stream that failed without setting it says so.
std::string errnoReason() {
    return errno ? std::strerror(errno) : "the system gave no reason";
}
}  // namespace

namespace {

void putLE32(unsigned char* b, uint32_t v) {
    for (int i = 0; i < 4; ++i) b[i] = static_cast<unsigned char>(v >> (8 * i));
}

/// Whether OpenEXR would flag the file as having names longer than 31 characters.
bool longNames(const Imf::Header& h) {
    for (auto it = h.begin(); it != h.end(); ++it)
        if (std::strlen(it.name()) > 31 || std::strlen(it.attribute().typeName()) > 31) return true;
    for (auto it = h.channels().begin(); it != h.channels().end(); ++it)
        if (std::strlen(it.name()) > 31) return true;
    return false;
}

struct Encoder {
    libdeflate_compressor* deflater;
    std::unique_ptr<unsigned char[]> rawOwned, splitOwned;
    unsigned char* raw = nullptr;    ///< a chunk's scan lines as stored
    unsigned char* split = nullptr;  ///< its bytes split and predicted, what deflate reads
    explicit Encoder(int level) : deflater(libdeflate_alloc_compressor(level)) {
        if (!deflater) throw std::bad_alloc();
    }
    ~Encoder() { libdeflate_free_compressor(deflater); }
    Encoder(const Encoder&) = delete;
    Encoder& operator=(const Encoder&) = delete;
};

}  // namespace

void writeZipScanlines(const std::string& path, const Imf::Header& header,
                       const std::vector<const void*>& planes, int threads, int level,
                       const ZipChunkHook& afterChunk, const Workspace& lent) {
    const Imath::Box2i dw = header.dataWindow();
    const size_t W = size_t(std::max(dw.max.x - dw.min.x + 1, 0));
    std::vector<size_t> rowBytes;
    for (auto it = header.channels().begin(); it != header.channels().end(); ++it)
        rowBytes.push_back(W * (it.channel().type == Imf::HALF ? 2 : 4));
    if (rowBytes.size() > planes.size())
        throw Error("writeZipScanlines: fewer planes than the header's channels");
    if (rowBytes.size() < planes.size())
        throw Error("writeZipScanlines: more planes than the header's channels");
    const ZipRowSource rows = [&](size_t c, size_t row, unsigned char* dst) {
        std::memcpy(dst, static_cast<const unsigned char*>(planes[c]) + row * rowBytes[c],
                    rowBytes[c]);
    };
    writeZipScanlines(path, header, rows, threads, level, afterChunk, lent);
}

void writeZipScanlines(const std::string& path, const Imf::Header& header, const ZipRowSource& rows,
                       int threads, int level, const ZipChunkHook& afterChunk,
                       const Workspace& lent) {
    const Imf::Compression compression = header.compression();
    if (compression != Imf::ZIP_COMPRESSION && compression != Imf::ZIPS_COMPRESSION)
        throw Error("writeZipScanlines: the header's compression is not ZIP or ZIPS");
    if (header.lineOrder() != Imf::INCREASING_Y)
        throw Error("writeZipScanlines: only increasing-y line order is written");
    header.sanityCheck(false);
    const Imath::Box2i dw = header.dataWindow();
    const size_t W = size_t(dw.max.x - dw.min.x + 1), H = size_t(dw.max.y - dw.min.y + 1);
    std::vector<size_t> chans;  // bytes per scan line of each channel
    size_t bytesPerLine = 0;
    for (auto it = header.channels().begin(); it != header.channels().end(); ++it) {
        const Imf::Channel& ch = it.channel();
        if ((ch.type != Imf::HALF && ch.type != Imf::FLOAT) || ch.xSampling != 1 ||
            ch.ySampling != 1)
            throw Error(std::string("writeZipScanlines: channel ") + it.name() +
                        " is not a full-resolution half or float channel");
        const size_t rowBytes = W * (ch.type == Imf::HALF ? 2 : 4);
        chans.push_back(rowBytes);
        bytesPerLine += rowBytes;
    }
    if (chans.empty()) throw Error("writeZipScanlines: the header has no channels");
    const size_t lines = compression == Imf::ZIP_COMPRESSION ? 16 : 1;
    const size_t chunks = (H + lines - 1) / lines;
    if (lines * bytesPerLine > size_t(std::numeric_limits<int32_t>::max()))
        throw Error("writeZipScanlines: a chunk would exceed 2 GB");

    // Encode (ImfZip.cpp's compress, with libdeflate): the chunk's scan lines (each channel's
    // values in turn), its bytes split into even and odd halves, each byte stored as its
    // difference from the one before plus 128, deflated in zlib format; kept as is when deflate
    // does not shrink it, as OpenEXR does.
    const int workers =
        std::clamp(int(std::min<size_t>(size_t(std::max(threads, 1)), chunks)), 1, 64);
    // A batch of chunks is encoded at once, then written: a few per worker keep them busy while
    // only the batch's encoded bytes are held (not the whole frame's). Each chunk is deflated
    // straight into its slot of the batch. Buffers: two per worker and one per slot, each a
    // chunk's size, in lent regions when there are enough of them that hold a chunk.
    const size_t chunkBytes = lines * bytesPerLine;
    const size_t want = size_t(workers) * 4;
    const size_t lendable = lent.bytes >= chunkBytes ? lent.regions.size() : 0;
    const bool useLent = lendable >= size_t(workers) * 3;
    const size_t batch =
        std::min(useLent ? std::min(want, lendable - size_t(workers) * 2) : want, chunks);
    auto region = [&](size_t i) { return reinterpret_cast<unsigned char*>(lent.regions[i]); };
    std::vector<std::unique_ptr<Encoder>> encoders(static_cast<size_t>(workers));
    for (size_t w = 0; w < encoders.size(); ++w) {
        auto& e = encoders[w];
        e = std::make_unique<Encoder>(std::clamp(level, 1, 12));
        if (useLent) {
            e->raw = region(2 * w);
            e->split = region(2 * w + 1);
        } else {
            e->rawOwned = std::make_unique_for_overwrite<unsigned char[]>(chunkBytes);
            e->splitOwned = std::make_unique_for_overwrite<unsigned char[]>(chunkBytes);
            e->raw = e->rawOwned.get();
            e->split = e->splitOwned.get();
        }
    }
    struct Slot {
        unsigned char* data = nullptr;
        size_t size = 0;
        std::unique_ptr<unsigned char[]> owned;
    };
    std::vector<Slot> encoded(batch);
    for (size_t k = 0; k < batch; ++k) {
        if (useLent) {
            encoded[k].data = region(size_t(workers) * 2 + k);
        } else {
            // Not zero-filled: only the bytes a chunk encodes to are written (and resident).
            encoded[k].owned = std::make_unique_for_overwrite<unsigned char[]>(chunkBytes);
            encoded[k].data = encoded[k].owned.get();
        }
    }
    auto encodeBatch = [&](size_t first, size_t count) {
        std::atomic<size_t> next{0};
        std::atomic<bool> failed{false};
        std::string failure;
        std::mutex failureLock;
        auto work = [&](Encoder& e) {  // never throws: it may run on a helper thread
            try {
                for (size_t k; !failed && (k = next++) < count;) {
                    const size_t i = first + k;
                    const size_t lines0 = std::min(lines, H - i * lines), n = lines0 * bytesPerLine;
                    unsigned char* r = e.raw;
                    for (size_t l = 0; l < lines0; ++l)
                        for (size_t c = 0; c < chans.size(); ++c) {
                            rows(c, i * lines + l, r);
                            r += chans[c];
                        }
                    const size_t half = (n + 1) / 2;
                    unsigned char *lo = e.split, *hi = lo + half;
                    for (size_t j = 0; j < n / 2; ++j) {
                        lo[j] = e.raw[2 * j];
                        hi[j] = e.raw[2 * j + 1];
                    }
                    if (n % 2) lo[n / 2] = e.raw[n - 1];
                    // The predictor in place, from the end (each delta needs the byte before
                    // it as it was); `raw` stays for a chunk deflate does not shrink.
                    for (size_t j = n - 1; j > 0; --j)
                        e.split[j] = static_cast<unsigned char>(e.split[j] - e.split[j - 1] + 128);
                    Slot& slot = encoded[k];
                    slot.size = libdeflate_zlib_compress(e.deflater, e.split, n, slot.data, n - 1);
                    if (slot.size == 0) {  // not smaller: the scan lines as they are
                        std::memcpy(slot.data, e.raw, n);
                        slot.size = n;
                    }
                }
            } catch (const std::exception& ex) {
                std::lock_guard<std::mutex> g(failureLock);
                if (!failed.exchange(true)) failure = ex.what();
            }
        };
        std::vector<std::thread> pool;
        const size_t helpers = std::min(size_t(workers), count) - 1;
        pool.reserve(helpers);
        try {
            for (size_t t = 0; t < helpers; ++t)
                pool.emplace_back(work, std::ref(*encoders[t + 1]));
        } catch (...) {
            // no more threads: the ones started and this one share the chunks
        }
        work(*encoders[0]);
        for (auto& t : pool) t.join();
        if (failed) throw Error("encoding: " + failure);
    };

    errno = 0;  // what the failing open or write sets is the reason the user is given
    std::ofstream file(path, std::ios::binary | std::ios::trunc);
    if (!file) throw Error("cannot create the file: " + errnoReason());
    {
        Imf::StdOFStream os(file, path.c_str());
        unsigned char b[8];
        putLE32(b, uint32_t(Imf::MAGIC));
        putLE32(b + 4, uint32_t(Imf::EXR_VERSION | (longNames(header) ? Imf::LONG_NAMES_FLAG : 0)));
        os.write(reinterpret_cast<const char*>(b), 8);
        header.writeTo(os, false);
        const uint64_t table = os.tellp();
        std::vector<unsigned char> offsets(chunks * 8, 0);
        os.write(reinterpret_cast<const char*>(offsets.data()), int(offsets.size()));
        for (size_t first = 0; first < chunks; first += batch) {
            const size_t count = std::min(batch, chunks - first);
            encodeBatch(first, count);
            for (size_t k = 0; k < count; ++k) {
                const size_t i = first + k;
                const uint64_t at = os.tellp();
                for (int j = 0; j < 8; ++j)
                    offsets[i * 8 + size_t(j)] = static_cast<unsigned char>(at >> (8 * j));
                putLE32(b, uint32_t(int32_t(dw.min.y + int(i * lines))));
                putLE32(b + 4, uint32_t(encoded[k].size));
                os.write(reinterpret_cast<const char*>(b), 8);
                os.write(reinterpret_cast<const char*>(encoded[k].data), int(encoded[k].size));
                if (afterChunk) {
                    // The chunks so far are in the file, as a failing disk leaves them.
                    file.flush();
                    afterChunk(i + 1);
                }
            }
        }
        os.seekp(table);
        os.write(reinterpret_cast<const char*>(offsets.data()), int(offsets.size()));
    }
    file.close();
    if (!file) throw Error("writing failed: " + errnoReason());
}

}  // namespace kestrel::exr
