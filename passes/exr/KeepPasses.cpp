#include "KeepPasses.h"

#include <OpenEXR/ImfChannelList.h>
#include <OpenEXR/ImfFrameBuffer.h>
#include <OpenEXR/ImfOutputFile.h>
#include <OpenEXR/ImfStandardAttributes.h>

#include <algorithm>
#include <cstring>
#include <vector>

#include "ExrInput.h"
#include "kestrel/Error.h"

namespace kestrel::exr {

namespace {

std::string joined(const std::vector<ChannelRef>& refs) {
    std::string s;
    for (const auto& r : refs) s += (s.empty() ? "" : ",") + r.name;
    return s;
}

std::set<std::string> split(const std::string& s) {
    std::set<std::string> out;
    for (size_t at = 0; at <= s.size();) {
        const size_t comma = std::min(s.find(',', at), s.size());
        if (comma > at) out.insert(s.substr(at, comma - at));
        at = comma + 1;
    }
    return out;
}

/// Attributes that describe the file's layout, which the output sets itself.
bool structural(const std::string& name) {
    static const std::set<std::string> names = {"channels",
                                                "compression",
                                                "dataWindow",
                                                "displayWindow",
                                                "lineOrder",
                                                "pixelAspectRatio",
                                                "screenWindowCenter",
                                                "screenWindowWidth",
                                                "tiles",
                                                "type",
                                                "name",
                                                "version",
                                                "chunkCount",
                                                "view",
                                                "multiView"};
    return names.count(name) > 0;
}

/// Copies the input's attributes the output should carry: not its layout, not what the writer
/// states itself (provenance, checksum: --resume trusts them), except the chromaticities, the
/// input's colour space being the output's.
void copyAttributes(const Imf::Header& from, Imf::Header& to) {
    std::set<std::string> own;
    for (auto it = to.begin(); it != to.end(); ++it) own.insert(it.name());
    for (auto it = from.begin(); it != from.end(); ++it) {
        const std::string name = it.name();
        if (structural(name) || (own.count(name) && name != "chromaticities")) continue;
        if (own.count(name)) to.erase(name);  // the input's type may differ
        to.insert(name, it.attribute());
    }
}

size_t bytesOf(Imf::PixelType t) {
    return t == Imf::HALF ? 2 : 4;
}

}  // namespace

void stateSourceFacts(ResolveContext& rc, const Plan& plan, const FramePattern* pattern) {
    if (!pattern || plan.layout == Layout::Games202) return;
    rc.setFact(kSourcePathFact, pattern->pattern());
    if (const Recipe* c = plan.find("color"); c && !c->absent)
        rc.setFact(kSourceColorFact, joined(c->channels()));
    if (const Recipe* a = plan.find("alpha"); a && !a->absent)
        rc.setFact(kSourceAlphaFact, joined(a->channels()));
}

KeptSource KeptSource::fromFacts(const ResolveContext& rc) {
    const auto path = rc.fact(kSourcePathFact);
    if (!path)
        throw Error(
            "keepPasses: no loader reads one EXR file per frame (canonical or Blender "
            "layout) whose passes could be kept; set keepPasses=false");
    return {FramePattern(*path), split(rc.fact(kSourceColorFact).value_or("")),
            split(rc.fact(kSourceAlphaFact).value_or(""))};
}

size_t writeKeepingPasses(const std::string& path, Imf::Header header, const std::string& input,
                          const std::set<std::string>& replaced, const OwnRow& own, int threads) {
    const Imath::Box2i dw = header.dataWindow();
    const int64_t W = dw.max.x - dw.min.x + 1, H = dw.max.y - dw.min.y + 1;
    // A render with overscan may have a data window larger than the frame: 4x is plenty.
    ExrInput in(input, 4 * W * H + 4096);
    Imf::InputFile& file = in.file();
    const Imf::Header& ih = file.header();

    std::set<std::string> ownNames;
    for (auto it = header.channels().begin(); it != header.channels().end(); ++it)
        ownNames.insert(it.name());
    std::vector<std::string> kept;
    for (auto it = ih.channels().begin(); it != ih.channels().end(); ++it) {
        const Imf::Channel& ch = it.channel();
        if (ownNames.count(it.name()) || replaced.count(it.name())) continue;
        if (ch.xSampling != 1 || ch.ySampling != 1) continue;  // subsampled chroma: not a pass
        header.channels().insert(it.name(), Imf::Channel(ch.type, 1, 1, ch.pLinear));
        kept.push_back(it.name());
    }
    copyAttributes(ih, header);

    // One buffer per channel for a block of rows, wide enough for both data windows (the
    // reader writes every pixel of the input's window that a row holds).
    const Imath::Box2i idw = ih.dataWindow();
    const int x0 = std::min(dw.min.x, idw.min.x), x1 = std::max(dw.max.x, idw.max.x);
    const size_t width = size_t(x1 - x0 + 1);
    const int block = 64;  // a multiple of every compression's lines per chunk
    std::vector<std::pair<std::string, Imf::PixelType>> channels;
    for (auto it = header.channels().begin(); it != header.channels().end(); ++it)
        channels.emplace_back(it.name(), it.channel().type);
    std::vector<std::vector<char>> planes(channels.size(),
                                          std::vector<char>(width * size_t(block) * 4));

    Imf::OutputFile out(path.c_str(), header, threads);
    for (int y0 = dw.min.y; y0 <= dw.max.y; y0 += block) {
        const int y1 = std::min(y0 + block - 1, dw.max.y);
        const Imath::Box2i rows({x0, y0}, {x1, y1});
        Imf::FrameBuffer ofb, ifb;
        for (size_t c = 0; c < channels.size(); ++c) {
            const auto& [name, type] = channels[c];
            char* plane = planes[c].data();
            const size_t elem = bytesOf(type);
            const Imf::Slice slice = Imf::Slice::Make(type, plane, rows, elem, elem * width);
            ofb.insert(name, slice);
            if (std::find(kept.begin(), kept.end(), name) != kept.end()) {
                std::memset(plane, 0, planes[c].size());  // outside the input's window: 0
                ifb.insert(name, slice);
            } else {
                for (int y = y0; y <= y1; ++y)
                    own(name, y - dw.min.y,
                        plane + (size_t(y - y0) * width + size_t(dw.min.x - x0)) * elem);
            }
        }
        const int r0 = std::max(y0, idw.min.y), r1 = std::min(y1, idw.max.y);
        if (!kept.empty() && r0 <= r1) {
            file.setFrameBuffer(ifb);
            file.readPixels(r0, r1);
        }
        out.setFrameBuffer(ofb);
        out.writePixels(y1 - y0 + 1);
    }
    return kept.size();
}

}  // namespace kestrel::exr
