#include "ChannelPlan.h"

#include <cmath>
#include <cstdlib>

#include "ChannelPresets.h"
#include "kestrel/Conventions.h"
#include "kestrel/Error.h"

namespace kestrel::exr {

const char* layoutName(Layout l) {
    switch (l) {
        case Layout::Canonical:
            return "canonical";
        case Layout::Blender:
            return "blender";
        case Layout::Games202:
            return "games202";
    }
    return "?";
}

std::vector<ChannelRef> Recipe::channels() const {
    std::vector<ChannelRef> out;
    std::vector<const std::vector<Term>*> lists = {&terms};
    if (!cap.empty()) lists.push_back(&cap);
    if (rest) lists.insert(lists.end(), {&rest->color, &rest->passes, &rest->emission});
    for (const auto* list : lists)
        for (const auto& t : *list)
            for (const auto& f : t)
                for (const auto& c : f) out.push_back(c);
    if (backgroundMask) out.push_back(*backgroundMask);
    if (skyDepth) out.push_back(*skyDepth);
    if (zeroFallback) out.insert(out.end(), zeroFallback->begin(), zeroFallback->end());
    if (reflectionOf)
        for (const Factor* f : {&reflectionOf->first, &reflectionOf->second})
            out.insert(out.end(), f->begin(), f->end());
    return out;
}

Recipe* Plan::find(const std::string& output) {
    for (auto& r : recipes)
        if (r.output == output) return &r;
    return nullptr;
}
const Recipe* Plan::find(const std::string& output) const {
    return const_cast<Plan*>(this)->find(output);
}

const std::vector<OutputSpec>& loaderOutputs() {
    static const std::vector<OutputSpec> outputs = {
        {"color", Format::Float3, 0.f, "noisy radiance, linear HDR", kMostNegativeLight},
        {"albedo", Format::Float3, 0.f, "surface albedo for demodulation", 0.f},
        {"jitteredAlbedo", Format::Float3, 0.f,
         "the albedo where the render is anti-aliased (a pixel filter wider than a pixel: one "
         "sample of the footprint per frame, to be averaged over frames); absent when the render "
         "is point-sampled",
         0.f},
        {"emission", Format::Float3, 0.f, "emitted radiance (incl. environment)",
         kMostNegativeLight},
        {"direct", Format::Float3, 0.f, "direct part of color (radiance)", kMostNegativeLight},
        {"indirect", Format::Float3, 0.f, "indirect part of color (radiance)", kMostNegativeLight},
        {"diffuse", Format::Float3, 0.f, "diffuse part of color (radiance)", kMostNegativeLight},
        {"diffuseAlbedo", Format::Float3, 0.f, "albedo of the diffuse part", 0.f},
        {"jitteredDiffuseAlbedo", Format::Float3, 0.f,
         "diffuseAlbedo where the render is anti-aliased (as jitteredAlbedo)", 0.f},
        {"specular", Format::Float3, 0.f, "specular/glossy part of color (radiance)",
         kMostNegativeLight},
        {"specularAlbedo", Format::Float3, 0.f, "albedo of the specular part", 0.f},
        {"jitteredSpecularAlbedo", Format::Float3, 0.f,
         "specularAlbedo where the render is anti-aliased (as jitteredAlbedo)", 0.f},
        {"normal", Format::Float3, 0.f, "world-space unit shading normal, 0 on background"},
        {"depth", Format::Float, kBackgroundDepth, "linear view depth, 1e10 on background"},
        {"position", Format::Float3, 0.f, "world-space position"},
        {"motion", Format::Float2, 0.f, "motion to the previous frame in pixels, y down"},
        {"objectId", Format::Int32, float(kBackgroundId), "object id, -1 on background"},
        {"alpha", Format::Float, 0.f,
         "coverage of the beauty (Blender Combined.A, canonical A), for the output's A channel; "
         "0 outside the data window"},
        {"reflection", Format::Float, 0.f,
         "1 where the pixel's features describe what a near-specular surface shows (a mirror, "
         "a polished floor: Cycles' denoising features pass such bounces), 0 elsewhere"},
        {"lightThroughMirror", Format::Float, 0.f,
         "1 where the camera path reached a light or the sky through near-specular bounces only "
         "(Cycles' Denoising Normal is zero on a surface): a smooth mirror's view of them, which "
         "a 1-spp render gets exact (KeepExact), 0 elsewhere"},
        {"pathLength", Format::Float, 0.f,
         "length of the camera path through near-specular bounces to the surface the features "
         "describe (Cycles' Denoising Depth), 0 on the background; where reflection is 1 it places "
         "the reflected point's virtual image on the camera ray (VirtualMotion)"},
    };
    return outputs;
}

const char* jitteredOf(std::string_view output) {
    if (output == "jitteredAlbedo") return "albedo";
    if (output == "jitteredDiffuseAlbedo") return "diffuseAlbedo";
    if (output == "jitteredSpecularAlbedo") return "specularAlbedo";
    return nullptr;
}

namespace {

const std::vector<std::vector<const char*>>& suffixSets(int n) {
    static const std::vector<std::vector<const char*>> s1 = {{"Z"}, {"Y"}, {"R"},
                                                             {"X"}, {"V"}, {"id"}};
    static const std::vector<std::vector<const char*>> s2 = {
        {"X", "Y"}, {"R", "G"}, {"U", "V"}, {"x", "y"}, {"u", "v"}};
    static const std::vector<std::vector<const char*>> s3 = {
        {"R", "G", "B"}, {"X", "Y", "Z"}, {"r", "g", "b"}, {"x", "y", "z"}};
    static const std::vector<std::vector<const char*>> s4 = {{"R", "G", "B", "A"},
                                                             {"X", "Y", "Z", "W"}};
    return n == 1 ? s1 : n == 2 ? s2 : n == 3 ? s3 : s4;
}

/// The n channels of `layer` ("" = top level) present in `channels`, trying the usual component
/// names; a one-channel group may also be a full channel name.
std::optional<Factor> resolveGroup(const ChannelSets& files, const std::string& file,
                                   const std::string& layer, int n) {
    auto it = files.find(file);
    if (it == files.end()) return std::nullopt;
    const auto& ch = it->second;
    if (n == 1 && !layer.empty() && ch.count(layer)) return Factor{{file, layer}};
    std::string prefix = layer.empty() ? "" : layer + ".";
    for (const auto& set : suffixSets(n)) {
        Factor f;
        for (const char* s : set)
            if (ch.count(prefix + s)) f.push_back({file, prefix + s});
        if (int(f.size()) == n) return f;
    }
    return std::nullopt;
}

std::string groupHint(const std::string& layer, int n) {
    std::string p = layer.empty() ? "" : layer + ".";
    if (n == 1) return p + "Z";
    if (n == 2) return p + "X/Y";
    return p + "R/G/B";
}

/// Builds recipes with a shared "missing channel" bookkeeping.
/// "A*B + C - D": the layers a recipe sums, multiplies and subtracts.
std::string describeTerms(const Recipe& r) {
    std::string s;
    auto add = [&](const Term& t, const char* sign) {
        if (!s.empty()) s += sign;
        for (size_t i = 0; i < t.size(); ++i) {
            if (i) s += "*";
            std::string c = t[i].front().str();
            auto dot = c.rfind('.');
            s += t[i].size() > 1 && dot != std::string::npos ? c.substr(0, dot) : c;
        }
    };
    for (const auto& t : r.terms) add(t, " + ");
    if (!r.cap.empty()) {
        Recipe capOnly;
        capOnly.terms = r.cap;
        s = "min(" + s + ", " + describeTerms(capOnly) + ")";
    }
    if (r.rest)
        s += std::string(s.empty() ? "" : " + ") + "the " +
             (r.rest->part == Recipe::Rest::Part::Positive ? "positive part of the " : "") +
             "light no split pass holds";
    return s;
}

struct Builder {
    Plan plan;
    const ChannelSets& files;
    Builder(Layout l, const ChannelSets& f) : files(f) {
        plan.layout = l;
        for (const auto& o : loaderOutputs()) {
            Recipe r;
            r.output = o.name;
            r.format = o.format;
            r.fill = o.fill;
            r.lowest = o.lowest;
            plan.recipes.push_back(r);
        }
    }
    int width(const Recipe& r) const {
        return r.format == Format::Int32 ? 1 : channelCount(r.format);
    }

    /// A group, or records the first missing one in `missing`.
    std::optional<Factor> group(const std::string& file, const std::string& layer, int n,
                                std::string& missing) {
        auto g = resolveGroup(files, file, layer, n);
        if (!g && missing.empty()) {
            if (!files.count(file))
                missing = (file.empty() ? "input" : file) + " file";
            else
                missing = (file.empty() ? "" : file + " file ") + "channel " + groupHint(layer, n);
        }
        return g;
    }
    /// out = sum of products of the given layers; absent (naming the first missing) otherwise.
    void set(const std::string& output, const std::vector<std::vector<std::string>>& terms,
             const std::string& file = {}) {
        Recipe& r = *plan.find(output);
        std::string missing;
        r.terms.clear();
        r.cap.clear();
        r.rest.reset();
        for (const auto& t : terms) {
            Term term;
            for (const auto& layer : t)
                if (auto g = group(file, layer, width(r), missing)) term.push_back(*g);
            r.terms.push_back(term);
        }
        describe(r, missing);
    }
    void describe(Recipe& r, const std::string& missing) {
        if (!missing.empty()) {
            r.absent = true;
            r.terms.clear();
            r.cap.clear();
            r.rest.reset();
            r.why = "layout " + std::string(layoutName(plan.layout)) + " has no " + missing;
            return;
        }
        r.absent = r.terms.empty();
        if (r.absent) {
            r.why = "layout " + std::string(layoutName(plan.layout)) + " provides no " + r.output;
            return;
        }
        r.why = describeTerms(r);
    }
    /// The first of `layers` the file has (its index), else absent naming the first layer (of
    /// `named`, when given) and Blender's UI path that enables it ("View Layer > Passes >
    /// <uiPath>"); -1 when absent.
    int setFirst(const std::string& output, const std::vector<std::string>& layers,
                 const std::string& uiPath, std::vector<std::string> named = {}) {
        for (size_t i = 0; i < layers.size(); ++i)
            if (resolveGroup(files, "", layers[i], width(*plan.find(output)))) {
                set(output, {{layers[i]}});
                return int(i);
            }
        if (named.empty()) named = layers;  // the order the message names them in
        std::string missing = "channel " + groupHint(named.front(), width(*plan.find(output)));
        for (size_t i = 1; i < named.size(); ++i) missing += (i == 1 ? " (nor " : ", ") + named[i];
        if (named.size() > 1) missing += ")";
        describe(*plan.find(output), missing + ": enable View Layer > Passes > " + uiPath);
        return -1;
    }
    void absent(const std::string& output, const std::string& missing) {
        describe(*plan.find(output), missing);
    }
};

}  // namespace

std::vector<std::string> blenderLayers(const std::set<std::string>& channels) {
    const std::string tail = ".Combined.R";
    std::vector<std::string> layers;  // in the set's (name) order
    for (const auto& c : channels)
        if (c.size() > tail.size() && c.compare(c.size() - tail.size(), tail.size(), tail) == 0)
            layers.push_back(c.substr(0, c.size() - tail.size()));
    return layers;
}

/// The canonical split's contract (docs/canonical-layout.md) is color == diffuse + specular +
/// emission, so a file with the split but without the emission AOV still holds it: the rest of
/// the colour (the sky, emitters). Without this the graphs would add no sky back (black).
static void addCanonicalEmission(Plan& plan) {
    const Recipe &color = *plan.find("color"), &diffuse = *plan.find("diffuse");
    const Recipe& specular = *plan.find("specular");
    Recipe& emission = *plan.find("emission");
    if (emission.rest && emission.terms.empty()) {  // derived before: derive again
        emission.rest.reset();
        emission.absent = true;
    }
    if (!emission.absent || color.absent || diffuse.absent || specular.absent) return;
    Recipe::Rest rest{color.terms, diffuse.terms, {}, Recipe::Rest::Part::Whole};
    rest.passes.insert(rest.passes.end(), specular.terms.begin(), specular.terms.end());
    emission.absent = false;
    emission.rest = rest;
    emission.why = "color - diffuse - specular (no emission channel)";
}

namespace {
/// A file whose channels are all bare names (R, G, B, A, Z) is a single-layer EXR: Blender's
/// "OpenEXR" format, which holds the Combined pass only. What it lacks is then not a channel
/// to enable but a format to choose: each absent output says so (docs/blender.md).
void explainSingleLayer(Plan& plan, const ChannelSets& files) {
    auto it = files.find("");
    if (it == files.end() || it->second.empty()) return;
    std::string names;
    for (const auto& c : it->second) {
        if (c.find('.') != std::string::npos) return;  // layered: a canonical or Blender file
        names += (names.empty() ? "" : ", ") + c;
    }
    const std::string prefix = "layout canonical has no ";
    for (auto& r : plan.recipes)
        if (r.absent && r.why.rfind(prefix, 0) == 0)
            r.why = "a single-layer EXR (channels " + names + ") has no " +
                    r.why.substr(prefix.size()) +
                    ": save the render as OpenEXR MultiLayer with its passes (Blender: Output "
                    "Properties > Output > File Format; docs/blender.md)";
}
}  // namespace

Plan planCanonical(const ChannelSets& files) {
    Builder b(Layout::Canonical, files);
    b.set("color", {{""}});
    for (const auto& o : loaderOutputs())
        if (std::string(o.name) != "color" && !jitteredOf(o.name)) {
            if (std::string(o.name) == "alpha") {
                b.set(o.name, {{"A"}});  // the colour's alpha, beside R, G, B
            } else if (std::string(o.name) == "objectId") {
                // "objectId.id" (the documented name) or any single channel of the layer.
                b.set(o.name, {{"objectId.id"}});
                if (b.plan.find("objectId")->absent) b.set(o.name, {{"objectId"}});
            } else {
                b.set(o.name, {{o.name}});
            }
        }
    // OpenEXR's own name for depth is a bare Z (Blender's single-layer "Z Buffer" option, many
    // renderers' beauty files); the canonical depth.Z wins where both exist.
    if (b.plan.find("depth")->absent && resolveGroup(files, "", "Z", 1)) b.set("depth", {{"Z"}});
    addCanonicalEmission(b.plan);
    explainSingleLayer(b.plan, files);
    return b.plan;
}

Plan planBlender(const ChannelSets& files, const std::string& L) {
    Builder b(Layout::Blender, files);
    auto has = [&](const std::string& pass) {
        return resolveGroup(files, "", L + "." + pass, 3).has_value();
    };
    auto P = [&](const char* pass) { return L + "." + pass; };
    // Light passes are divided by their colour pass (data/README.md):
    // Combined = (DiffDir + DiffInd)*DiffCol + (GlossDir + GlossInd)*GlossCol + Emit + Env.
    b.set("color", {{P("Combined")}});
    // Cycles writes Combined as RGBA: with Film > Transparent the alpha is the coverage a
    // compositor needs (1 everywhere otherwise).
    b.setFirst("alpha", {P("Combined.A")}, "Combined (RGBA)");
    // What a user who ticks "Denoising Data" has stands in for a missing G-buffer pass (Cycles'
    // denoiser features: data/README.md); the proper passes win where both exist.
    b.setFirst("albedo", {P("DiffCol"), P("Denoising Albedo")}, "Light > Diffuse > Color");
    std::vector<std::vector<std::string>> emission;
    if (has("Emit")) emission.push_back({P("Emit")});
    if (has("Env")) emission.push_back({P("Env")});
    if (emission.empty())
        b.absent("emission", "channel " + P("Emit") + ".R/G/B (nor " + P("Env") + ")");
    else
        b.set("emission", emission);
    if (Recipe& e = *b.plan.find("emission"); !e.absent) {
        e.cap = b.plan.find("color")->terms;
        e.why = describeTerms(e);
    }
    // The specular chain filters every non-diffuse light the render splits out: glossy, and
    // transmission (glass) and volume where the scene enables those passes.
    std::vector<std::vector<std::string>> specular, specularAlbedo = {{P("GlossCol")}};
    const bool transmission = has("TransCol") && (has("TransDir") || has("TransInd"));
    for (const char* part : {"Dir", "Ind"}) {
        specular.push_back({P("Gloss") + part, P("GlossCol")});
        if (transmission && has(std::string("Trans") + part))
            specular.push_back({P("Trans") + part, P("TransCol")});
        if (has(std::string("Volume") + part)) specular.push_back({P("Volume") + part});
    }
    if (transmission) specularAlbedo.push_back({P("TransCol")});
    for (const char* part : {"Dir", "Ind"}) {
        std::vector<std::vector<std::string>> terms = {{P("Diff") + part, P("DiffCol")},
                                                       {P("Gloss") + part, P("GlossCol")}};
        // Transmission and volume light add to Combined when the scene enables those passes.
        if (has(std::string("Trans") + part) && has("TransCol"))
            terms.push_back({P("Trans") + part, P("TransCol")});
        if (has(std::string("Volume") + part)) terms.push_back({P("Volume") + part});
        b.set(std::string(part) == "Dir" ? "direct" : "indirect", terms);
    }
    b.set("diffuse", {{P("DiffDir"), P("DiffCol")}, {P("DiffInd"), P("DiffCol")}});
    b.set("diffuseAlbedo", {{P("DiffCol")}});
    b.set("specular", specular);
    b.set("specularAlbedo", specularAlbedo);
    addSplitRest(b.plan);
    // Cycles' Denoising Normal passes through mirrors and glass to the surface they show, so a
    // reflection is filtered within the edges of what it reflects; the Normal pass gives the
    // mirror's own, flat normal there (svgf.json frames 5-12: blender-street 31.62 -> 34.59 dB,
    // blender-street-defaults 30.71 -> 32.11, the sample room unchanged). It is in camera space,
    // turned to world space where camera.json gives the camera; without one it stays in camera
    // space, which only a turn of more than ~9 degrees per frame would make Reprojection's
    // normal test reject (still 31.62 -> 34.55 and 30.66 -> 31.94 dB there).
    if (b.setFirst("normal", {P("Denoising Normal"), P("Normal")}, "Data > Normal",
                   {P("Normal"), P("Denoising Normal")}) == 0) {
        Recipe& normal = *b.plan.find("normal");
        normal.cameraSpace = true;  // Cycles writes its features in camera space
        normal.zeroFallback = resolveGroup(files, "", P("Normal"), 3);
        if (normal.zeroFallback) {
            Recipe& reflection = *b.plan.find("reflection");
            reflection.reflectionOf = {normal.terms[0][0], *normal.zeroFallback};
            reflection.absent = false;
            reflection.why = "where " + P("Denoising Normal") + " names another surface than " +
                             P("Normal") + " (needs the camera)";
            Recipe& light = *b.plan.find("lightThroughMirror");
            light.reflectionOf = reflection.reflectionOf;
            light.lightOnly = true;
            light.absent = false;
            light.why =
                "where " + P("Denoising Normal") + " is zero and " + P("Normal") + " is not";
        }
    }
    if (!b.plan.find("lightThroughMirror")->reflectionOf)
        b.absent("lightThroughMirror", "channels " + P("Denoising Normal") + " and " + P("Normal") +
                                           " (both: where the first is zero and the second not, "
                                           "the path passed a mirror to a light or the sky)");
    if (!b.plan.find("reflection")->reflectionOf)
        b.absent("reflection", "channels " + P("Denoising Normal") + " and " + P("Normal") +
                                   " (both: where they differ, the features passed a mirror)");
    // Planar depth, 1e10 on the background already; else the denoiser's ray-path length, 0 on
    // the background: a depth guide of its own kind (not planar), consistent frame to frame.
    const int depthFrom = b.setFirst("depth", {P("Depth"), P("Denoising Depth")}, "Data > Z");
    if (depthFrom == 1) b.plan.find("depth")->zeroIsBackground = true;
    // Denoising Depth is a path length through the near-specular bounces the features pass
    // (data/README.md): where reflection is set, the distance along the camera ray to the
    // reflected surface's virtual image (NRD ReBLUR's virtual motion). Only beside a planar
    // Depth: where depth itself reads Denoising Depth it would repeat it.
    if (depthFrom == 0)
        b.setFirst("pathLength", {P("Denoising Depth")}, "Data > Denoising Data");
    else
        b.absent("pathLength", "planar " + P("Depth") +
                                   ".Z beside Denoising Depth (depth reads the path length "
                                   "itself, or neither exists): enable View Layer > Passes > "
                                   "Data > Z");
    b.setFirst("position", {P("Position")}, "Data > Position");
    b.setFirst("motion", {P("Vector")}, "Data > Vector");
    b.plan.find("motion")->scale[1] = -1.f;  // Blender's Vector y points up the image
    b.setFirst("objectId", {P("IndexOB")}, "Data > Indexes > Object Index");
    b.plan.find("objectId")->idRule = IdRule::BlenderZeroIsBackground;
    return b.plan;
}

void addSplitRest(Plan& plan, const std::set<std::string>& keep) {
    if (plan.layout == Layout::Canonical) {
        if (!keep.count("emission")) addCanonicalEmission(plan);
        return;
    }
    const Recipe &color = *plan.find("color"), &diffuse = *plan.find("diffuse");
    Recipe &specular = *plan.find("specular"), &emission = *plan.find("emission");
    if (plan.layout != Layout::Blender || color.absent || diffuse.absent || specular.absent) return;
    Recipe::Rest rest{color.terms, diffuse.terms, {}};
    rest.passes.insert(rest.passes.end(), specular.terms.begin(), specular.terms.end());
    if (!emission.absent) rest.emission = emission.terms;
    if (!emission.absent && !keep.count("emission")) {
        emission.cap = color.terms;  // the colour the channels parameter may have set
        emission.why = describeTerms(emission);
    }
    if (!keep.count("specular")) {
        specular.rest = rest;
        specular.why = describeTerms(specular);
    } else if (!keep.count("emission")) {
        // The user's specular takes none of the rest: emission keeps all of it, unfiltered.
        emission.absent = false;
        emission.rest = rest;
        emission.rest->part = Recipe::Rest::Part::Whole;
        emission.why = describeTerms(emission);
    }
}

Plan planGames202(const ChannelSets& files) {
    Builder b(Layout::Games202, files);
    b.set("color", {{""}}, "beauty");
    b.set("normal", {{""}}, "normal");
    b.set("position", {{""}}, "position");
    b.set("depth", {{"Y"}}, "depth");
    b.set("objectId", {{"Y"}}, "ID");
    Recipe& depth = *b.plan.find("depth");
    // Depth is 0 on the background; the ID buffer (-1 there) marks it (data/README.md).
    if (!depth.absent && resolveGroup(files, "ID", "Y", 1))
        depth.backgroundMask = ChannelRef{"ID", "Y"};
    for (const char* o :
         {"albedo", "emission", "direct", "indirect", "diffuse", "diffuseAlbedo", "specular",
          "specularAlbedo", "motion", "reflection", "lightThroughMirror", "pathLength", "alpha"})
        b.absent(o,
                 std::string("buffer for ") + o + " (it has beauty, normal, position, depth, ID)");
    return b.plan;
}

namespace {

/// `s` cut at each `sep` outside parentheses (a per-channel constant "(1,-1)" holds commas).
std::vector<std::string> splitOutsideParens(const std::string& s, char sep) {
    std::vector<std::string> parts(1);
    int depth = 0;
    for (char c : s) {
        depth += c == '(' ? 1 : c == ')' ? -1 : 0;
        if (c == sep && depth == 0)
            parts.emplace_back();
        else
            parts.back() += c;
    }
    return parts;
}

/// A number as the whole of `text`, or nullopt.
std::optional<float> number(const std::string& text) {
    if (text.empty()) return std::nullopt;
    char* end = nullptr;
    const float v = std::strtof(text.c_str(), &end);
    if (end != text.c_str() + text.size() || !std::isfinite(v)) return std::nullopt;
    return v;
}

/// A constant factor: a number ("-0.5": every channel) or one per channel ("(1,-1)"), as `n`
/// scales; nullopt when `g` is no constant (a channel group). Throws Error for a constant with
/// the wrong number of values or a value that is no number.
std::optional<std::vector<float>> constantFactor(const std::string& g, int n) {
    if (auto v = number(g)) return std::vector<float>(size_t(n), *v);
    if (g.size() < 2 || g.front() != '(' || g.back() != ')') return std::nullopt;
    std::vector<float> values;
    for (const auto& part : splitOutsideParens(g.substr(1, g.size() - 2), ',')) {
        auto v = number(part);
        if (!v) throw Error("'" + part + "' in " + g + " is not a number");
        values.push_back(*v);
    }
    if (int(values.size()) != n)
        throw Error(g + " has " + std::to_string(values.size()) + " values for an output of " +
                    std::to_string(n) + " channel(s)");
    return values;
}

/// Resets everything a layout set on `r`, for an expression to set it anew.
void clearRecipe(Recipe& r) {
    r.terms.clear();
    r.cap.clear();
    r.rest.reset();
    r.backgroundMask.reset();
    r.skyDepth.reset();
    r.zeroFallback.reset();
    r.reflectionOf.reset();
    r.lightOnly = false;
    r.zeroIsBackground = r.cameraSpace = r.fromDepth = r.rayLength = false;
    r.scale[0] = r.scale[1] = r.scale[2] = r.scale[3] = 1.f;
}

/// Sets `r` from `expr` (docs/layouts.md, "The channels override"). Throws Error saying why not.
void applyExpression(Recipe& r, const std::string& expr, const ChannelSets& files) {
    const int n = r.format == Format::Int32 ? 1 : channelCount(r.format);
    const auto terms = splitOutsideParens(expr, '+');
    bool scaled = false;
    for (const auto& term : terms) {
        Term t;
        for (std::string g : splitOutsideParens(term, '*')) {
            if (auto k = constantFactor(g, n)) {
                // The loader scales an output after summing its terms: a constant can scale
                // only an expression of one term.
                if (terms.size() > 1)
                    throw Error("a constant (" + g +
                                ") may scale only an expression of "
                                "one term (no '+')");
                for (int c = 0; c < n; ++c) r.scale[c] *= (*k)[size_t(c)];
                scaled = true;
                continue;
            }
            std::string file;
            if (auto colon = g.find(':'); colon != std::string::npos) {
                file = g.substr(0, colon);
                g = g.substr(colon + 1);
            }
            if (g.empty()) throw Error("empty channel group");
            auto f = resolveGroup(files, file, g, n);
            if (!f)
                throw Error("the file has no channel group '" + g + "' with " + std::to_string(n) +
                            " channel(s) (tried " + groupHint(g, n) + ", ...)");
            t.push_back(*f);
        }
        if (t.empty()) throw Error("a term of constants only (it needs a channel group)");
        r.terms.push_back(t);
    }
    if (scaled && r.format == Format::Int32) throw Error("an id output cannot be scaled");
}

}  // namespace

std::set<std::string> applyChannelOverrides(Plan& plan, const std::string& spec,
                                            const ChannelSets& files) {
    std::set<std::string> set;
    for (std::string item : splitOutsideParens(expandChannelPresets(spec), ',')) {
        // "?out=EXPR" (what presets expand to): only where the file has the channels.
        const bool optional = !item.empty() && item[0] == '?';
        if (optional) item.erase(0, 1);
        if (item.empty()) continue;
        auto bad = [&](const std::string& why) {
            return Error("channels: '" + item + "': " + why +
                         " (expected output=Layer[*Layer][+...] or a constant factor, e.g. "
                         "albedo=ViewLayer.DiffCol, motion=Vector*(1,-1); or @preset)");
        };
        auto eq = item.find('=');
        if (eq == std::string::npos) throw bad("missing '='");
        std::string out = item.substr(0, eq), expr = item.substr(eq + 1);
        Recipe* r = plan.find(out);
        if (!r) throw bad("no loader output named '" + out + "'");
        Recipe recipe = *r;
        clearRecipe(recipe);
        if (expr.empty()) {
            recipe.absent = true;
            recipe.why = "the channels parameter leaves it out";
        } else {
            try {
                applyExpression(recipe, expr, files);
            } catch (const Error& e) {
                if (optional) continue;
                throw bad(e.what());
            }
            recipe.absent = false;
            recipe.why = expr + " (channels parameter)";
        }
        *r = std::move(recipe);
        set.insert(out);
    }
    return set;
}

}  // namespace kestrel::exr
