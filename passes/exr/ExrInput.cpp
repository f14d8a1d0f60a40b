#include "ExrInput.h"

#include <OpenEXR/ImfStdIO.h>
#include <OpenEXR/ImfThreading.h>
#include <OpenEXR/ImfVersion.h>

#include <filesystem>

#include "kestrel/Error.h"

namespace kestrel::exr {

namespace {
Box toBox(const Imath::Box2i& b) {
    return {b.min.x, b.min.y, b.max.x, b.max.y};
}

void checkWindow(const char* what, const Box& b, int64_t maxPixels) {
    if (b.width() <= 0 || b.height() <= 0) throw Error(std::string("empty or inverted ") + what);
    // Both factors fit in 33 bits, so the product cannot overflow int64.
    if (b.width() * b.height() > maxPixels)
        throw Error(std::string(what) + " " + std::to_string(b.width()) + "x" +
                    std::to_string(b.height()) + " exceeds maxPixels " + std::to_string(maxPixels) +
                    " (refused before allocating)");
}
}  // namespace

ExrInput::ExrInput(const std::string& path, int64_t maxPixels) : path_(path) {
    std::error_code ec;
    if (!std::filesystem::is_regular_file(path, ec)) throw Error("file not found");
    try {
        stream_ = std::make_unique<Imf::StdIFStream>(path.c_str());
        char magic[4] = {};
        stream_->read(magic, 4);
        if (!Imf::isImfMagic(magic)) throw Error("not an OpenEXR file (bad magic number)");
        unsigned char v[4] = {};
        stream_->read(reinterpret_cast<char*>(v), 4);
        int version = int(v[0] | (v[1] << 8) | (v[2] << 16) | (unsigned(v[3]) << 24));
        if (Imf::getVersion(version) != Imf::EXR_VERSION ||
            !Imf::supportsFlags(Imf::getFlags(version)))
            throw Error("unsupported OpenEXR version field");
        if (Imf::isNonImage(version)) throw Error("deep images are not supported");
        // Header only: attributes, no pixel or offset-table allocation yet.
        Imf::Header probe;
        probe.readFrom(*stream_, version);
        data_ = toBox(probe.dataWindow());
        display_ = toBox(probe.displayWindow());
        checkWindow("data window", data_, maxPixels);
        checkWindow("display window", display_, maxPixels);
        probe.sanityCheck(Imf::isTiled(version), Imf::isMultiPart(version));
        stream_->seekg(0);
        file_ = std::make_unique<Imf::InputFile>(*stream_, Imf::globalThreadCount());
    } catch (const Error&) {
        throw;
    } catch (const std::exception& e) {
        throw Error(std::string("corrupt or unreadable OpenEXR header: ") + e.what());
    }
}

ExrInput::~ExrInput() = default;

}  // namespace kestrel::exr
