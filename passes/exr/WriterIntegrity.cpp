#include "WriterIntegrity.h"

#include <OpenEXR/ImfChannelList.h>
#include <OpenEXR/ImfFrameBuffer.h>
#include <OpenEXR/ImfHeader.h>
#include <OpenEXR/ImfInputFile.h>
#include <OpenEXR/ImfStdIO.h>
#include <OpenEXR/ImfStringAttribute.h>
#include <OpenEXR/ImfVersion.h>
#include <fcntl.h>
#include <libdeflate.h>
#include <unistd.h>

#include <cerrno>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <vector>

#include "ExrInput.h"
#include "ZipWriter.h"
#include "kestrel/Error.h"

namespace kestrel::exr {

namespace fs = std::filesystem;

static uint64_t readLE(const unsigned char* b, int bytes) {
    uint64_t v = 0;
    for (int i = bytes - 1; i >= 0; --i) v = (v << 8) | b[i];
    return v;
}

/// Whether every chunk of a single-part scan-line file lies wholly inside the file: its offset
/// table entry is set, and the chunk's header and data end before the file does. A frame cut
/// short by a crash fails this even when its offset table was written (the writer writes the
/// table last, but other writers do not).
static bool chunksPresent(std::ifstream& f, Imf::StdIFStream& is, const Imf::Header& h,
                          uint64_t size) {
    const int lines = linesPerChunk(h.compression());
    const Imath::Box2i dw = h.dataWindow();
    if (dw.max.y < dw.min.y) return false;
    const uint64_t chunks = (uint64_t(dw.max.y - dw.min.y) + uint64_t(lines)) / uint64_t(lines);
    const uint64_t table = is.tellg();
    if (table + chunks * 8 > size) return false;
    std::vector<unsigned char> offsets(chunks * 8);
    f.seekg(std::streamoff(table));
    if (!f.read(reinterpret_cast<char*>(offsets.data()), std::streamsize(offsets.size())))
        return false;
    for (uint64_t i = 0; i < chunks; ++i) {
        const uint64_t at = readLE(&offsets[i * 8], 8);
        unsigned char head[8];
        if (at < table + chunks * 8 || at + 8 > size) return false;
        f.seekg(std::streamoff(at));
        if (!f.read(reinterpret_cast<char*>(head), 8)) return false;
        const uint64_t bytes = readLE(head + 4, 4);
        if (bytes == 0 || bytes > 0x7fffffffu || at + 8 + bytes > size) return false;
    }
    return true;
}

namespace {
/// A file descriptor closed when it goes out of scope.
struct Fd {
    int fd;
    ~Fd() {
        if (fd >= 0) ::close(fd);
    }
};
}  // namespace

/// CRC-32 of the bytes of `fd` from `from` to `to`, read a megabyte at a time.
static uint32_t crcOfRange(int fd, uint64_t from, uint64_t to) {
    std::vector<unsigned char> buf(std::min<uint64_t>(to - from, 1u << 20));
    uint32_t crc = 0;
    for (uint64_t at = from; at < to;) {
        const ssize_t got =
            ::pread(fd, buf.data(), size_t(std::min<uint64_t>(buf.size(), to - at)), off_t(at));
        if (got <= 0) throw Error(std::string("cannot read back: ") + std::strerror(errno));
        crc = libdeflate_crc32(crc, buf.data(), size_t(got));
        at += uint64_t(got);
    }
    return crc;
}

static std::string hex8(uint32_t v) {
    char text[9];
    std::snprintf(text, sizeof text, "%08x", v);
    return text;
}

/// Fills the placeholder of kCrcAttribute in the (closed) file `path`, whose header ends at
/// `headerEnd`, with the CRC of everything after the header. In place, the header's size and
/// every offset unchanged.
void stampChecksum(const std::string& path, uint64_t headerEnd) {
    const Fd file{::open(path.c_str(), O_RDWR | O_CLOEXEC)};
    const int fd = file.fd;
    if (fd < 0) throw Error(std::string("cannot open to checksum: ") + std::strerror(errno));
    const off_t size = ::lseek(fd, 0, SEEK_END);
    if (size < 0 || uint64_t(size) < headerEnd) throw Error("file shorter than its header");
    const std::string crc = hex8(crcOfRange(fd, headerEnd, uint64_t(size)));
    std::string head(headerEnd, '\0');
    if (::pread(fd, head.data(), head.size(), 0) != ssize_t(head.size()))
        throw Error(std::string("cannot read back the header: ") + std::strerror(errno));
    // name, type name, 4-byte little-endian size (8), value: OpenEXR's attribute layout.
    const std::string key = std::string(kCrcAttribute) + '\0' + "string" + '\0' +
                            std::string("\x08\0\0\0", 4) + kCrcPlaceholder;
    const auto at = head.find(key);
    if (at == std::string::npos) throw Error("no checksum placeholder in the header");
    const off_t valueAt = off_t(at + key.size() - 8);
    if (::pwrite(fd, crc.data(), 8, valueAt) != 8)
        throw Error(std::string("cannot write the checksum: ") + std::strerror(errno));
}

/// Where the header of a single-part scan-line file ends (its offset table starts).
uint64_t headerEndOf(const std::string& path) {
    Imf::Header h;
    std::ifstream f(path, std::ios::binary);
    Imf::StdIFStream is(f, path.c_str());
    unsigned char magic[8];
    if (!f.read(reinterpret_cast<char*>(magic), 8)) throw Error("cannot read the header");
    int version = int(readLE(magic + 4, 4));
    h.readFrom(is, version);
    return is.tellg();
}

/// Reads every pixel of `path` through OpenEXR, which throws on a chunk that does not decode:
/// the check for files without kestrel.dataCrc32 (older or from another writer).
static void decodeAll(const std::string& path) {
    Imf::InputFile in(path.c_str(), 1);
    const Imath::Box2i dw = in.header().dataWindow();
    const size_t W = size_t(dw.max.x - dw.min.x + 1), H = size_t(dw.max.y - dw.min.y + 1);
    std::vector<float> plane(W * H);
    for (auto it = in.header().channels().begin(); it != in.header().channels().end(); ++it) {
        Imf::FrameBuffer fb;  // one channel at a time: one plane of memory
        fb.insert(it.name(),
                  Imf::Slice::Make(Imf::FLOAT, plane.data(), dw, sizeof(float), W * sizeof(float)));
        in.setFrameBuffer(fb);
        in.readPixels(dw.min.y, dw.max.y);
    }
}

/// Why the file cannot be trusted as this run's output (empty: it can). Checked in order of
/// cost: magic and header; the run's provenance (`provenance` empty: not compared); every
/// chunk inside the file; the checksum of the offset table and chunks, or, for a file without
/// one, every chunk decoded. Tiled, multi-part and deep files (not what this writer makes) are
/// trusted when OpenEXR finds all their pixels.
std::string exrProblem(const std::string& path, const std::string& provenance) {
    const std::string broken = "is incomplete, corrupt or unreadable";
    try {
        std::ifstream f(path, std::ios::binary | std::ios::ate);
        if (!f) return broken;
        const uint64_t size = uint64_t(f.tellg());
        f.seekg(0);
        unsigned char magic[8];
        if (size < 8 || !f.read(reinterpret_cast<char*>(magic), 8)) return broken;
        const int version = int(readLE(magic + 4, 4));
        if (int(readLE(magic, 4)) != Imf::MAGIC) return broken;
        if (Imf::isTiled(version) || Imf::isMultiPart(version) || Imf::isNonImage(version)) {
            f.close();
            Imf::InputFile in(path.c_str(), 1);
            return in.isComplete() ? "" : broken;
        }
        Imf::StdIFStream is(f, path.c_str());
        Imf::Header h;
        int v = version;
        h.readFrom(is, v);
        const uint64_t table = is.tellg();
        if (!provenance.empty()) {
            const auto* p = h.findTypedAttribute<Imf::StringAttribute>("kestrel.provenance");
            if (!p || p->value() != provenance)
                return "was written by another graph or other parameters (its "
                       "kestrel.provenance is not this run's)";
        }
        if (!chunksPresent(f, is, h, size)) return broken;
        f.close();
        const auto* crc = h.findTypedAttribute<Imf::StringAttribute>(kCrcAttribute);
        if (!crc) {
            decodeAll(path);  // throws on a chunk that does not decode
            return "";
        }
        const Fd file{::open(path.c_str(), O_RDONLY | O_CLOEXEC)};
        if (file.fd < 0) return broken;
        if (hex8(crcOfRange(file.fd, table, size)) != crc->value())
            return "is corrupt (its data does not match its checksum)";
        return "";
    } catch (const std::exception&) {
        return broken;  // a header or chunk OpenEXR cannot parse: rewrite the frame
    }
}

/// A PNG with its signature first and its closing IEND chunk last: what a write cut short,
/// or one that failed and was never renamed into place, lacks.
bool isCompletePng(const std::string& path) {
    static const unsigned char signature[8] = {0x89, 'P', 'N', 'G', '\r', '\n', 0x1a, '\n'};
    static const unsigned char iend[12] = {0, 0, 0, 0, 'I', 'E', 'N', 'D', 0xae, 0x42, 0x60, 0x82};
    std::ifstream f(path, std::ios::binary | std::ios::ate);
    if (!f) return false;
    const std::streamoff size = f.tellg();
    unsigned char head[8], tail[12];
    if (size < std::streamoff(sizeof head + sizeof tail)) return false;
    f.seekg(0);
    if (!f.read(reinterpret_cast<char*>(head), sizeof head)) return false;
    f.seekg(size - std::streamoff(sizeof tail));
    if (!f.read(reinterpret_cast<char*>(tail), sizeof tail)) return false;
    return std::memcmp(head, signature, sizeof head) == 0 &&
           std::memcmp(tail, iend, sizeof tail) == 0;
}

}  // namespace kestrel::exr
