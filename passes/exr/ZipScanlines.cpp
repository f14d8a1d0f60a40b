#include "ZipScanlines.h"

#include <Imath/half.h>
#include <OpenEXR/ImfChannelList.h>
#include <OpenEXR/ImfCompression.h>
#include <fcntl.h>
#include <libdeflate.h>
#include <sys/mman.h>
#include <unistd.h>

#if defined(__SSE2__)
#include <emmintrin.h>
#endif

#include <algorithm>
#include <atomic>
#include <cerrno>
#include <cstring>
#include <limits>
#include <mutex>
#include <new>
#include <system_error>
#include <thread>

namespace kestrel::exr {

namespace {

int valueBytes(Imf::PixelType t) {
    return t == Imf::HALF ? 2 : 4;
}

uint64_t readLE64(const unsigned char* b) {
    uint64_t v = 0;
    for (int i = 7; i >= 0; --i) v = v << 8 | b[i];
    return v;
}
int32_t readLE32(const unsigned char* b) {
    return int32_t(uint32_t(b[0]) | uint32_t(b[1]) << 8 | uint32_t(b[2]) << 16 |
                   uint32_t(b[3]) << 24);
}

/// pread until `n` bytes or the end of the file; false on a short read or an error.
bool readAt(int fd, uint64_t pos, unsigned char* dst, size_t n) {
    while (n > 0) {
        const ssize_t r = ::pread(fd, dst, n, off_t(pos));
        if (r < 0 && errno == EINTR) continue;
        if (r <= 0) return false;
        dst += r;
        pos += uint64_t(r);
        n -= size_t(r);
    }
    return true;
}

/// Where a chunk's bytes are after inflating: OpenEXR's ZIP compressor stores byte j of the
/// scan-line data at j/2 of the first half (even j) or of the second half (odd j), after a
/// byte-delta predictor (ImfZip.cpp). Split reads byte pairs (j, j+1) for even j straight from
/// the two halves, so no reordered copy of the chunk is made.
struct Split {
    const unsigned char *lo, *hi;                                 // even and odd bytes
    void bytes(uint64_t j, size_t n, unsigned char* dst) const {  // j and n even
        const unsigned char* a = lo + j / 2;
        const unsigned char* b = hi + j / 2;
        for (size_t m = 0; m < n / 2; ++m) {
            dst[2 * m] = a[m];
            dst[2 * m + 1] = b[m];
        }
    }
    uint16_t word(uint64_t j) const { return uint16_t(lo[j / 2] | hi[j / 2] << 8); }
};
/// A chunk stored uncompressed (OpenEXR keeps the raw bytes when deflate does not shrink them).
struct Plain {
    const unsigned char* p;
    void bytes(uint64_t j, size_t n, unsigned char* dst) const { std::memcpy(dst, p + j, n); }
    uint16_t word(uint64_t j) const { return uint16_t(p[j] | p[j + 1] << 8); }
};

/// `count` values of one channel starting at byte j of the chunk data, as floats (little-endian
/// file values; HALF widened exactly, UINT converted as OpenEXR converts it).
template <class Src>
void convert(const Src& src, uint64_t j, Imf::PixelType type, size_t count, float* dst) {
    if (type == Imf::HALF) {
        // Imath's table, as OpenEXR converts: exact, NaN payloads kept (F16C's conversion,
        // which Imath::half picks under -march=native, sets the quiet bit of signalling NaNs).
        for (size_t i = 0; i < count; ++i)
            dst[i] = imath_half_to_float_table[src.word(j + 2 * i)].f;
        return;
    }
    src.bytes(j, count * 4, reinterpret_cast<unsigned char*>(dst));
    if (type == Imf::UINT)
        for (size_t i = 0; i < count; ++i) {
            uint32_t u;
            std::memcpy(&u, dst + i, 4);
            dst[i] = float(u);
        }
}

/// Undoes OpenEXR's ZIP predictor (ImfZip.cpp): byte i was stored as its difference from byte
/// i - 1, plus 128, so the data is t[0] followed by a running sum (mod 256) of t[i] - 128. The
/// scalar sum is a one-byte-per-add dependency chain; SSE2 sums 16 bytes in four shifted adds
/// and carries the last byte on: 0.33 ms per 3 MB chunk against 2.27 (docs/benchmarks.md).
void undoPredictor(unsigned char* t, size_t n) {
    if (n == 0) return;
    size_t i = 1;
    unsigned char p = t[0];
#if defined(__SSE2__)
    const __m128i bias = _mm_set1_epi8(char(-128));
    __m128i carry = _mm_set1_epi8(char(p));
    for (; i + 16 <= n; i += 16) {
        __m128i x = _mm_add_epi8(_mm_loadu_si128(reinterpret_cast<const __m128i*>(t + i)), bias);
        x = _mm_add_epi8(x, _mm_slli_si128(x, 1));
        x = _mm_add_epi8(x, _mm_slli_si128(x, 2));
        x = _mm_add_epi8(x, _mm_slli_si128(x, 4));
        x = _mm_add_epi8(x, _mm_slli_si128(x, 8));
        x = _mm_add_epi8(x, carry);
        _mm_storeu_si128(reinterpret_cast<__m128i*>(t + i), x);
        // byte 15 to every byte
        carry = _mm_shuffle_epi32(_mm_shufflehi_epi16(_mm_unpackhi_epi8(x, x), 0xff), 0xff);
    }
    if (i > 1) p = t[i - 1];
#endif
    for (; i < n; ++i) t[i] = p = static_cast<unsigned char>(p + t[i] - 128);
}

}  // namespace

#if defined(__SANITIZE_ADDRESS__)
#define KESTREL_EXACT_BUFFERS 1
#elif defined(__has_feature)
#if __has_feature(address_sanitizer)
#define KESTREL_EXACT_BUFFERS 1
#endif
#endif

/// Bytes mapped from the system and unmapped when freed: a chunk of a 1080p frame is megabytes,
/// which malloc would keep in the (per-thread) arena of a decoding thread after the frame, as
/// resident memory nobody uses. Under AddressSanitizer, heap buffers of exactly the size asked
/// instead, so that a read or write past a chunk's bytes is reported.
class MappedBytes {
public:
    MappedBytes() = default;
    ~MappedBytes() { release(); }
    MappedBytes(const MappedBytes&) = delete;
    MappedBytes& operator=(const MappedBytes&) = delete;
    /// At least n bytes (contents not kept).
    unsigned char* reserve(size_t n) {
#if defined(KESTREL_EXACT_BUFFERS)
        exact_.reset(new unsigned char[n]);
        return exact_.get();
#endif
        if (n <= size_) return p_;
        release();
        void* m = ::mmap(nullptr, n, PROT_READ | PROT_WRITE, MAP_PRIVATE | MAP_ANONYMOUS, -1, 0);
        if (m == MAP_FAILED) throw std::bad_alloc();
        p_ = static_cast<unsigned char*>(m);
        size_ = n;
        return p_;
    }

private:
    void release() {
        if (p_) ::munmap(p_, size_);
        p_ = nullptr;
        size_ = 0;
    }
    unsigned char* p_ = nullptr;
    size_t size_ = 0;
#if defined(KESTREL_EXACT_BUFFERS)
    std::unique_ptr<unsigned char[]> exact_;
#endif
};

/// A file descriptor closed at scope end.
struct Fd {
    int fd;
    explicit Fd(const std::string& path) : fd(::open(path.c_str(), O_RDONLY | O_CLOEXEC)) {}
    ~Fd() {
        if (fd >= 0) ::close(fd);
    }
    Fd(const Fd&) = delete;
    Fd& operator=(const Fd&) = delete;
};

struct ChunkBuffers {
    libdeflate_decompressor* inflater = libdeflate_alloc_decompressor();
    MappedBytes packed, unpacked;
    /// Lent memory (Workspace) used instead of packed and unpacked where set: each holds a
    /// whole chunk.
    unsigned char* lentPacked = nullptr;
    unsigned char* lentUnpacked = nullptr;
    ChunkBuffers() {
        if (!inflater) throw std::bad_alloc();
    }
    ~ChunkBuffers() { libdeflate_free_decompressor(inflater); }
    ChunkBuffers(const ChunkBuffers&) = delete;
    ChunkBuffers& operator=(const ChunkBuffers&) = delete;
};

std::unique_ptr<ZipScanlines> ZipScanlines::plan(const std::string& path, const Imf::Header& h,
                                                 bool singlePartScanlines, Imf::IStream& in,
                                                 uint64_t tablePos, uint64_t fileSize) {
    if (!singlePartScanlines) return nullptr;
    const Imf::Compression c = h.compression();
    if (c != Imf::ZIP_COMPRESSION && c != Imf::ZIPS_COMPRESSION) return nullptr;
    auto z = std::unique_ptr<ZipScanlines>(new ZipScanlines);
    z->path_ = path;
    const Imath::Box2i dw = h.dataWindow();
    z->data_ = {dw.min.x, dw.min.y, dw.max.x, dw.max.y};
    z->linesPerChunk_ = c == Imf::ZIP_COMPRESSION ? 16 : 1;
    const uint64_t width = uint64_t(z->data_.width());
    for (auto it = h.channels().begin(); it != h.channels().end(); ++it) {
        const Imf::Channel& ch = it.channel();
        if (ch.xSampling != 1 || ch.ySampling != 1) return nullptr;
        if (ch.type != Imf::HALF && ch.type != Imf::FLOAT && ch.type != Imf::UINT) return nullptr;
        z->channels_.push_back({it.name(), ch.type, z->bytesPerLine_});
        z->bytesPerLine_ += width * uint64_t(valueBytes(ch.type));
    }
    if (z->channels_.empty()) return nullptr;  // nothing to decode: OpenEXR says what it says
    if (h.lineOrder() != Imf::INCREASING_Y && h.lineOrder() != Imf::DECREASING_Y) return nullptr;
    z->decreasing_ = h.lineOrder() == Imf::DECREASING_Y;
    const uint64_t chunks = (uint64_t(z->data_.height()) + uint64_t(z->linesPerChunk_) - 1) /
                            uint64_t(z->linesPerChunk_);
    if (chunks > uint64_t(std::numeric_limits<int>::max()) / 8) return nullptr;  // OpenEXR's
    z->offsets_.resize(chunks);
    in.seekg(tablePos);
    in.read(reinterpret_cast<char*>(z->offsets_.data()), int(chunks * 8));
    for (uint64_t& o : z->offsets_) {
        o = readLE64(reinterpret_cast<const unsigned char*>(&o));
        // A zero entry marks a file whose writer stopped early: OpenEXR then rebuilds the whole
        // table by walking the chunks, which this path does not do.
        if (o == 0) return nullptr;
    }
    z->tableEnd_ = tablePos + chunks * 8;
    z->fileSize_ = fileSize;
    return z;
}

bool ZipScanlines::decodeChunk(int fd, int chunk, const std::vector<float*>& dst,
                               const std::vector<AbsurdFix>& fix, const Box& dp, int W,
                               ChunkBuffers& buf, bool* stored, std::string* why) const {
    auto where = [chunk] { return "chunk " + std::to_string(chunk); };  // on failure only
    const uint64_t off = offsets_[size_t(chunk)];
    unsigned char head[8];
    if (off < tableEnd_ || off > fileSize_ - std::min<uint64_t>(fileSize_, 8) ||
        !readAt(fd, off, head, 8)) {
        *why = where() + ": offset " + std::to_string(off) + " outside the file";
        return false;
    }
    const int32_t y = readLE32(head), size = readLE32(head + 4);
    const int64_t y0 = int64_t(data_.y0) + int64_t(chunk) * linesPerChunk_;
    if (y != y0) {
        *why =
            where() + ": starts at line " + std::to_string(y) + ", expected " + std::to_string(y0);
        return false;
    }
    const int lines = int(std::min<int64_t>(linesPerChunk_, int64_t(data_.y1) - y0 + 1));
    const uint64_t unpacked = uint64_t(lines) * bytesPerLine_;
    if (size <= 0 || uint64_t(size) > unpacked || uint64_t(size) > fileSize_ - off - 8) {
        *why = where() + ": " + std::to_string(size) + " bytes of data do not fit";
        return false;
    }
    // OpenEXR reads the chunk after the one it has just read from where that one ended, without
    // the table, so the same pixels come out only if the table says so too: chunks stored one
    // after another in line order, as every writer stores them.
    const size_t after = decreasing_ ? size_t(chunk) - 1 : size_t(chunk) + 1;
    if ((decreasing_ ? chunk > 0 : size_t(chunk) + 1 < offsets_.size()) &&
        offsets_[after] != off + 8 + uint64_t(size)) {
        *why = where() + ": the next chunk in the file is not where the offset table puts it";
        return false;
    }
    unsigned char* packed = buf.lentPacked ? buf.lentPacked : buf.packed.reserve(size_t(size));
    if (!readAt(fd, off + 8, packed, size_t(size))) {
        *why = where() + ": short read";
        return false;
    }
    auto write = [&](const auto& src) {
        const int64_t ix0 = std::max(data_.x0, dp.x0), ix1 = std::min(data_.x1, dp.x1);
        const size_t count = size_t(ix1 - ix0 + 1);
        for (int l = 0; l < lines; ++l) {
            const int64_t yy = y0 + l;
            if (yy < dp.y0 || yy > dp.y1) continue;
            const uint64_t line = uint64_t(l) * bytesPerLine_;
            for (size_t c = 0; c < channels_.size(); ++c) {
                if (!dst[c]) continue;
                const Channel& ch = channels_[c];
                const uint64_t j =
                    line + ch.lineOffset +
                    uint64_t(ix0 - int64_t(data_.x0)) * uint64_t(valueBytes(ch.type));
                float* row = dst[c] + size_t(yy - dp.y0) * size_t(W) + size_t(ix0 - int64_t(dp.x0));
                convert(src, j, ch.type, count, row);
                // While the row is in cache: no second pass over the plane.
                if (fix[c].on)
                    if (const size_t n = replaceAbsurd(row, count, fix[c].fill, fix[c].lowest))
                        *fix[c].replaced += n;
            }
        }
    };
    *stored = uint64_t(size) == unpacked;
    if (*stored) {  // kept as is
        write(Plain{packed});
        return true;
    }
    unsigned char* t = buf.lentUnpacked ? buf.lentUnpacked : buf.unpacked.reserve(size_t(unpacked));
    size_t got = 0;
    if (libdeflate_zlib_decompress(buf.inflater, packed, size_t(size), t, size_t(unpacked), &got) !=
            LIBDEFLATE_SUCCESS ||
        got != unpacked) {
        *why = where() + ": corrupt deflate data";
        return false;
    }
    undoPredictor(t, size_t(unpacked));
    write(Split{t, t + (unpacked + 1) / 2});
    return true;
}

bool ZipScanlines::decode(const Box& dp, int W,
                          const std::vector<std::pair<std::string, float*>>& chans,
                          const std::vector<float>& fill, int threads, std::string* why,
                          Stats* stats, const Workspace& lent,
                          const std::vector<AbsurdFix>& fixes) const {
    std::vector<float*> dst(channels_.size(), nullptr);
    std::vector<AbsurdFix> fix(channels_.size());  // by file channel, as dst
    for (size_t k = 0; k < chans.size(); ++k) {
        auto it = std::find_if(channels_.begin(), channels_.end(),
                               [&](const Channel& c) { return c.name == chans[k].first; });
        if (it != channels_.end()) {
            dst[size_t(it - channels_.begin())] = chans[k].second;
            if (!fixes.empty()) fix[size_t(it - channels_.begin())] = fixes[k];
        } else {  // as OpenEXR fills a slice the file lacks
            std::fill(chans[k].second, chans[k].second + size_t(W) * size_t(dp.height()), fill[k]);
        }
    }
    const int iy0 = std::max(data_.y0, dp.y0), iy1 = std::min(data_.y1, dp.y1);
    if (iy0 > iy1 || std::max(data_.x0, dp.x0) > std::min(data_.x1, dp.x1)) return true;
    const int first = int((int64_t(iy0) - data_.y0) / linesPerChunk_);
    const int last = int((int64_t(iy1) - data_.y0) / linesPerChunk_);

    std::vector<std::thread> pool;
    const int helpers = std::clamp(std::min(threads, last - first + 1) - 1, 0, 63);
    pool.reserve(size_t(helpers));
    const Fd file(path_);
    if (file.fd < 0) {
        *why = "cannot open: " + std::error_code(errno, std::generic_category()).message();
        return false;
    }
    const int fd = file.fd;
    // Chunks are handed out in order from one counter; each writes its own rows, so the planes
    // do not depend on the thread count.
    std::atomic<int> next{first};
    std::atomic<bool> failed{false};
    std::atomic<int> decoded{0}, stored{0};
    std::mutex whyLock;
    auto fail = [&](const std::string& reason) {
        std::lock_guard<std::mutex> g(whyLock);
        if (!failed.exchange(true)) *why = reason;
    };
    // Threads that take two lent regions (packed and inflated): each must hold a whole chunk.
    const uint64_t chunkBytes = uint64_t(linesPerChunk_) * bytesPerLine_;
    const size_t lendable = lent.bytes >= chunkBytes ? lent.regions.size() / 2 : 0;
    auto work = [&](size_t worker) {  // never throws: it may run on a helper thread
        try {
            ChunkBuffers buf;
            if (worker < lendable) {
                buf.lentPacked = reinterpret_cast<unsigned char*>(lent.regions[2 * worker]);
                buf.lentUnpacked = reinterpret_cast<unsigned char*>(lent.regions[2 * worker + 1]);
            }
            std::string mine;
            for (int c; !failed && (c = next++) <= last;) {
                bool raw = false;
                if (!decodeChunk(fd, c, dst, fix, dp, W, buf, &raw, &mine)) {
                    fail(mine);
                    break;
                }
                ++decoded;
                stored += raw;
            }
        } catch (const std::exception& e) {
            fail(std::string("decoding: ") + e.what());
        }
    };
    try {
        for (int i = 0; i < helpers; ++i) pool.emplace_back(work, size_t(i) + 1);
    } catch (...) {
        // no more threads: the ones started and this one share the chunks
    }
    work(0);
    for (auto& t : pool) t.join();
    if (stats) *stats = {decoded, stored};
    return !failed;
}

}  // namespace kestrel::exr
