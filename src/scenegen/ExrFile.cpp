#include "ExrFile.h"

#include <OpenEXR/ImfChannelList.h>
#include <OpenEXR/ImfFrameBuffer.h>
#include <OpenEXR/ImfHeader.h>
#include <OpenEXR/ImfIntAttribute.h>
#include <OpenEXR/ImfMatrixAttribute.h>
#include <OpenEXR/ImfOutputFile.h>
#include <OpenEXR/ImfStringAttribute.h>

#include <cstdio>
#include <stdexcept>

namespace kestrel::scenegen {

namespace fs = std::filesystem;

namespace {

fs::path temporaryName(const fs::path& path) {
    fs::path tmp = path;
    tmp += ".tmp";
    return tmp;
}

void commit(const fs::path& tmp, const fs::path& path) {
    std::error_code ec;
    fs::rename(tmp, path, ec);
    if (ec) {
        fs::remove(tmp, ec);
        throw std::runtime_error("scenegen: cannot rename " + tmp.string() + " to " +
                                 path.string());
    }
}

}  // namespace

void writeExr(const fs::path& path, int width, int height, const std::vector<ExrChannel>& channels,
              const ExrAttributes& attributes) {
    Imf::Header header(width, height);
    header.compression() = Imf::ZIP_COMPRESSION;
    header.lineOrder() = Imf::INCREASING_Y;
    // zlib level 1: the files are test data, writing speed matters more than 10% of size.
    header.zipCompressionLevel() = 1;
    for (const auto& [name, value] : attributes.strings)
        header.insert(name, Imf::StringAttribute(value));
    for (const auto& [name, value] : attributes.ints) header.insert(name, Imf::IntAttribute(value));
    for (const auto& a : attributes.matrices) {
        Imath::M44f m;
        for (int r = 0; r < 4; ++r)
            for (int c = 0; c < 4; ++c) m[r][c] = a.m.m[size_t(r)][size_t(c)];
        header.insert(a.name, Imf::M44fAttribute(m));
    }
    Imf::FrameBuffer fb;
    for (const auto& ch : channels) {
        header.channels().insert(ch.name, Imf::Channel(Imf::FLOAT));
        fb.insert(ch.name,
                  Imf::Slice(Imf::FLOAT, reinterpret_cast<char*>(const_cast<float*>(ch.data)),
                             sizeof(float), sizeof(float) * size_t(width)));
    }
    const fs::path tmp = temporaryName(path);
    try {
        Imf::OutputFile file(tmp.c_str(), header);
        file.setFrameBuffer(fb);
        file.writePixels(height);
    } catch (const std::exception& e) {
        std::error_code ec;
        fs::remove(tmp, ec);
        throw std::runtime_error("scenegen: cannot write " + path.string() + ": " + e.what());
    }
    commit(tmp, path);
}

void writeFileAtomic(const fs::path& path, const std::vector<char>& bytes) {
    const fs::path tmp = temporaryName(path);
    std::FILE* f = std::fopen(tmp.c_str(), "wb");
    if (!f) throw std::runtime_error("scenegen: cannot write " + tmp.string());
    const bool ok = std::fwrite(bytes.data(), 1, bytes.size(), f) == bytes.size();
    if (std::fclose(f) != 0 || !ok) {
        std::error_code ec;
        fs::remove(tmp, ec);
        throw std::runtime_error("scenegen: cannot write " + tmp.string());
    }
    commit(tmp, path);
}

}  // namespace kestrel::scenegen
