#include "ZipWriter.h"

#include <OpenEXR/ImfChannelList.h>
#include <OpenEXR/ImfStdIO.h>
#include <OpenEXR/ImfVersion.h>
#include <libdeflate.h>

#include <algorithm>
#include <atomic>
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
    std::vector<unsigned char> raw, split, out;
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
                       const ZipChunkHook& afterChunk) {
    const Imf::Compression compression = header.compression();
    if (compression != Imf::ZIP_COMPRESSION && compression != Imf::ZIPS_COMPRESSION)
        throw Error("writeZipScanlines: the header's compression is not ZIP or ZIPS");
    if (header.lineOrder() != Imf::INCREASING_Y)
        throw Error("writeZipScanlines: only increasing-y line order is written");
    header.sanityCheck(false);
    const Imath::Box2i dw = header.dataWindow();
    const size_t W = size_t(dw.max.x - dw.min.x + 1), H = size_t(dw.max.y - dw.min.y + 1);
    struct Chan {
        const unsigned char* data;
        size_t rowBytes;
    };
    std::vector<Chan> chans;
    size_t bytesPerLine = 0;
    for (auto it = header.channels().begin(); it != header.channels().end(); ++it) {
        const Imf::Channel& ch = it.channel();
        if ((ch.type != Imf::HALF && ch.type != Imf::FLOAT) || ch.xSampling != 1 ||
            ch.ySampling != 1)
            throw Error(std::string("writeZipScanlines: channel ") + it.name() +
                        " is not a full-resolution half or float channel");
        if (chans.size() == planes.size())
            throw Error("writeZipScanlines: fewer planes than the header's channels");
        const size_t rowBytes = W * (ch.type == Imf::HALF ? 2 : 4);
        chans.push_back({static_cast<const unsigned char*>(planes[chans.size()]), rowBytes});
        bytesPerLine += rowBytes;
    }
    if (chans.size() != planes.size())
        throw Error("writeZipScanlines: more planes than the header's channels");
    if (chans.empty()) throw Error("writeZipScanlines: the header has no channels");
    const size_t lines = compression == Imf::ZIP_COMPRESSION ? 16 : 1;
    const size_t chunks = (H + lines - 1) / lines;
    if (lines * bytesPerLine > size_t(std::numeric_limits<int32_t>::max()))
        throw Error("writeZipScanlines: a chunk would exceed 2 GB");

    // Encode (ImfZip.cpp's compress, with libdeflate): the chunk's scan lines (each channel's
    // values in turn), its bytes split into even and odd halves, each byte stored as its
    // difference from the one before plus 128, deflated in zlib format; kept as is when deflate
    // does not shrink it, as OpenEXR does.
    std::vector<std::vector<unsigned char>> encoded(chunks);
    std::atomic<size_t> next{0};
    std::atomic<bool> failed{false};
    std::string failure;
    std::mutex failureLock;
    auto work = [&] {  // never throws: it may run on a helper thread
        try {
            Encoder e(std::clamp(level, 1, 12));
            for (size_t i; !failed && (i = next++) < chunks;) {
                const size_t rows = std::min(lines, H - i * lines), n = rows * bytesPerLine;
                e.raw.resize(n);
                e.split.resize(n);
                e.out.resize(n);
                unsigned char* r = e.raw.data();
                for (size_t l = 0; l < rows; ++l)
                    for (const Chan& c : chans) {
                        std::memcpy(r, c.data + (i * lines + l) * c.rowBytes, c.rowBytes);
                        r += c.rowBytes;
                    }
                const size_t half = (n + 1) / 2;
                unsigned char *lo = e.split.data(), *hi = lo + half;
                for (size_t j = 0; j < n / 2; ++j) {
                    lo[j] = e.raw[2 * j];
                    hi[j] = e.raw[2 * j + 1];
                }
                if (n % 2) lo[n / 2] = e.raw[n - 1];
                // The predictor in place, from the end (each delta needs the byte before it
                // as it was); `raw` stays for a chunk deflate does not shrink.
                for (size_t j = n - 1; j > 0; --j)
                    e.split[j] = static_cast<unsigned char>(e.split[j] - e.split[j - 1] + 128);
                const size_t size =
                    libdeflate_zlib_compress(e.deflater, e.split.data(), n, e.out.data(), n - 1);
                if (size > 0)
                    encoded[i].assign(e.out.begin(), e.out.begin() + ptrdiff_t(size));
                else  // not smaller: the scan lines as they are
                    encoded[i] = e.raw;
            }
        } catch (const std::exception& ex) {
            std::lock_guard<std::mutex> g(failureLock);
            if (!failed.exchange(true)) failure = ex.what();
        }
    };
    const int helpers =
        std::clamp(int(std::min<size_t>(size_t(std::max(threads, 1)), chunks)) - 1, 0, 63);
    std::vector<std::thread> pool;
    pool.reserve(size_t(helpers));
    try {
        for (int i = 0; i < helpers; ++i) pool.emplace_back(work);
    } catch (...) {
        // no more threads: the ones started and this one share the chunks
    }
    work();
    for (auto& t : pool) t.join();
    if (failed) throw Error("encoding: " + failure);

    std::ofstream file(path, std::ios::binary | std::ios::trunc);
    if (!file) throw Error("cannot create the file");
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
        for (size_t i = 0; i < chunks; ++i) {
            const uint64_t at = os.tellp();
            for (int k = 0; k < 8; ++k)
                offsets[i * 8 + size_t(k)] = static_cast<unsigned char>(at >> (8 * k));
            putLE32(b, uint32_t(int32_t(dw.min.y + int(i * lines))));
            putLE32(b + 4, uint32_t(encoded[i].size()));
            os.write(reinterpret_cast<const char*>(b), 8);
            os.write(reinterpret_cast<const char*>(encoded[i].data()), int(encoded[i].size()));
            if (afterChunk) {
                file.flush();  // the chunks so far are in the file, as a failing disk leaves them
                afterChunk(i + 1);
            }
        }
        os.seekp(table);
        os.write(reinterpret_cast<const char*>(offsets.data()), int(offsets.size()));
    }
    file.close();
    if (!file) throw Error("writing failed (disk full?)");
}

}  // namespace kestrel::exr
