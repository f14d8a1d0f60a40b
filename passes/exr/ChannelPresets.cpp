#include "ChannelPresets.h"

#include <map>

#include "kestrel/Error.h"

namespace kestrel::exr {

namespace {

// Each preset maps only AOVs whose names (and, for motion, conventions) the renderer's public
// documentation states; an output left out keeps what the layout found (docs/layouts.md). Items
// are "?out=EXPR": applied where the file has the AOV, so a render without one still loads.
const std::map<std::string, std::string>& presets() {
    static const std::map<std::string, std::string> table = {
        // Arnold: built-in AOVs (Arnold Developer Guide, "AOVs": A, Z, P world-space position,
        // N normal) and built-in light path expression AOVs (Arnold User Guide, "Light Path
        // Expression AOVs": RGBA, direct, indirect, emission, diffuse, specular, albedo,
        // diffuse_albedo, specular_albedo). The beauty RGBA is the file's R, G, B, A. Not
        // mapped: motionvector (documented only as "screen space motion vector"; its direction
        // and scale follow the shutter: give motion=motionvector*K once checked) and ID (UINT).
        {"arnold",
         "?albedo=albedo,?emission=emission,?direct=direct,?indirect=indirect,"
         "?diffuse=diffuse,?diffuseAlbedo=diffuse_albedo,?specular=specular,"
         "?specularAlbedo=specular_albedo,?normal=N,?position=P,?depth=Z"},
        // Houdini Karma: the Karma Standard Render Vars LOP (Houdini documentation) names the
        // beauty C (RGBA), the emission component "emission" and the diffuse components
        // "combineddiffuse", "directdiffuse", "indirectdiffuse". Its ray-level outputs (normal,
        // position, depth, motion) are named by the user's render vars: add them as items.
        {"karma", "?color=C,?emission=emission"},
    };
    return table;
}

std::string known() {
    std::string names;
    for (const auto& [name, spec] : presets()) names += (names.empty() ? "@" : ", @") + name;
    return names;
}

}  // namespace

std::string expandChannelPresets(const std::string& spec) {
    std::string out;
    size_t at = 0;
    while (at <= spec.size()) {
        size_t comma = spec.find(',', at);
        if (comma == std::string::npos) comma = spec.size();
        std::string item = spec.substr(at, comma - at);
        if (!item.empty() && item[0] == '@') {
            const auto it = presets().find(item.substr(1));
            if (it == presets().end())
                throw Error("channels: no preset '" + item + "' (presets: " + known() + ")");
            item = it->second;
        }
        out += (out.empty() ? "" : ",") + item;
        at = comma + 1;
    }
    return out;
}

}  // namespace kestrel::exr
