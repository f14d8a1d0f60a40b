// The scene zoo: named configurations that together cover what real content has and the room
// lacks. Each is small enough to render in the test suite.
#include <stdexcept>

#include "scenegen/SceneGen.h"

namespace kestrel::scenegen {

namespace {

using Kind = SceneOptions::Kind;

SceneOptions zooBase(Kind kind) {
    SceneOptions o;
    o.kind = kind;
    o.width = 96;
    o.height = 64;
    o.frames = 12;
    o.referenceSpp = 256;
    return o;
}

}  // namespace

std::vector<ZooScene> zooScenes() {
    std::vector<ZooScene> zoo;
    zoo.push_back({"room", zooBase(Kind::Room),
                   "the default interior: diffuse only, textured floor and boxes, area light, "
                   "glowing sphere, sliding sphere, black sky at the sides"});
    SceneOptions cut = zooBase(Kind::Room);
    cut.cameraCutFrame = 7;
    zoo.push_back({"room-cut", cut, "the room with a camera cut at frame 7 (history must reset)"});
    SceneOptions lamp = zooBase(Kind::Room);
    lamp.lightSwing = 1.1f;
    zoo.push_back({"room-lamp", lamp,
                   "the room with its ceiling light swinging from side to side (1.1 m): the lit "
                   "pool and the shadows move where the geometry does not, so the history must "
                   "let go of the old light there and keep it everywhere else"});
    zoo.push_back({"street", zooBase(Kind::Street),
                   "outdoor: gradient sky (color = emission, depth 1e10), sun, brick paving a few "
                   "px per brick, window-grid facades with glossy windows, a glossy gold sphere, "
                   "a mirror sphere, an emissive pink sign, a lamp post and a fence 1-2 px wide, "
                   "a red van crossing (disocclusion), camera dolly + pan"});
    SceneOptions jittered = zooBase(Kind::Street);
    jittered.pixelFilterWidth = 1.5f;
    zoo.push_back({"street-jittered", jittered,
                   "the street with a 1.5 px Blackman-Harris pixel filter: jittered G-buffer, "
                   "anti-aliased reference"});
    SceneOptions still = zooBase(Kind::Street);
    still.staticCamera = true;
    zoo.push_back({"street-static", still,
                   "the street seen from a still camera: only the van moves (disocclusion "
                   "without camera motion)"});
    SceneOptions cloud = zooBase(Kind::Street);
    cloud.lightChangeFrame = 7;
    cloud.lightChangeScale = 0.2f;
    zoo.push_back({"street-cloud", cloud,
                   "the street with the sun dimmed to 0.2x from frame 7 on (a cloud; the lamp "
                   "too): the lighting changes where the geometry does not, so the history "
                   "must not keep the old light"});
    zoo.push_back({"fireflies", zooBase(Kind::StreetNight),
                   "the street at night: dim sky, a small intense lamp the 1-spp frames reach "
                   "only by BSDF sampling (rare very bright samples, also through the glossy "
                   "spheres); the reference samples it directly and converges"});
    return zoo;
}

ZooScene zooScene(const std::string& name) {
    std::string known;
    for (ZooScene& z : zooScenes()) {
        if (z.name == name) return z;
        known += (known.empty() ? "" : ", ") + z.name;
    }
    throw std::invalid_argument("scenegen: unknown scene '" + name + "' (known: " + known + ")");
}

}  // namespace kestrel::scenegen
