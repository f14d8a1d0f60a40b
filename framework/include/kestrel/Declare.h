#pragma once
// Typed pass declarations: a pass type declares its ports and parameters once, and reads them
// through what the declaration returns, never by a string.
//
//   struct MixParams { float weight = 0.5f; };          // the default, written once
//   struct MixPorts : kestrel::Declaration<MixParams> {
//       kestrel::InputPort a = input("a", Format::Float3, "the colour at weight 0");
//       kestrel::OutputPort color = output("color", Format::Float3, "the blend");
//       MixPorts() : Declaration("Mix", "Linear blend ...") {
//           param("weight", &MixParams::weight, 0.0, 1.0, "share of b");
//       }
//   };
//
// The PassDesc (what `kestrel passes`, JSON validation and the docs show) is derived from the
// declaration; a port is a handle whose index is its place in that PassDesc, so a misspelt port
// does not compile, and PassIO finds it without a name lookup; the parameters arrive as the
// struct, read once when the pass is constructed (Declaration::read).
#include <charconv>
#include <cstdint>
#include <functional>
#include <initializer_list>
#include <string>
#include <type_traits>
#include <utility>
#include <vector>

#include "kestrel/Pass.h"

namespace kestrel {

template <class Params>
class Declaration {
public:
    Declaration(std::string type, std::string description)
        : desc_(std::move(type), std::move(description)) {}
    Declaration(const Declaration&) = delete;
    Declaration& operator=(const Declaration&) = delete;

    const PassDesc& desc() const { return desc_; }

    /// The parameters' values (ParamValues checked against the PassDesc by the compiler) as
    /// the struct.
    Params read(const ParamValues& values) const {
        Params p{};
        for (const auto& r : readers_) r(p, values);
        return p;
    }

protected:
    InputPort input(std::string name, Format f, std::string description) {
        desc_.input(name, f, std::move(description));
        return InputPort{int(desc_.ports.size()) - 1, std::move(name)};
    }
    InputPort optionalInput(std::string name, Format f, std::string description) {
        desc_.optionalInput(name, f, std::move(description));
        return InputPort{int(desc_.ports.size()) - 1, std::move(name)};
    }
    InputPort historyInput(std::string name, Format f, std::string description) {
        desc_.historyInput(name, f, std::move(description));
        return InputPort{int(desc_.ports.size()) - 1, std::move(name)};
    }
    /// An output; with `inPlaceOf`, one that may be written into that input's memory
    /// (PassDesc::inPlaceOf: the pass is pointwise on the pair).
    OutputPort output(std::string name, Format f, std::string description,
                      const InputPort* inPlaceOf = nullptr) {
        desc_.output(name, f, std::move(description));
        if (inPlaceOf) desc_.inPlaceOf(inPlaceOf->name);
        return OutputPort{int(desc_.ports.size()) - 1, std::move(name)};
    }

    /// A parameter read into `member`; its default is the member's value in `Params{}`.
    void param(std::string name, float Params::*member, double min, double max,
               std::string description) {
        desc_.paramFloat(name, double(Params{}.*member), min, max, std::move(description));
        readers_.push_back(
            [member, name](Params& p, const ParamValues& v) { p.*member = v.getFloat(name); });
    }
    void param(std::string name, int Params::*member, int64_t min, int64_t max,
               std::string description) {
        desc_.paramInt(name, int64_t(Params{}.*member), min, max, std::move(description));
        readers_.push_back(
            [member, name](Params& p, const ParamValues& v) { p.*member = int(v.getInt(name)); });
    }
    void param(std::string name, bool Params::*member, std::string description) {
        desc_.paramBool(name, Params{}.*member, std::move(description));
        readers_.push_back(
            [member, name](Params& p, const ParamValues& v) { p.*member = v.getBool(name); });
    }
    void param(std::string name, std::string Params::*member, std::string description) {
        desc_.paramString(name, Params{}.*member, std::move(description));
        readers_.push_back(
            [member, name](Params& p, const ParamValues& v) { p.*member = v.getString(name); });
    }
    /// An enum parameter read into an enum member: `choices` names the values in order.
    template <class E>
    requires std::is_enum_v<E>
    void param(std::string name, E Params::*member, std::vector<std::string> choices,
               std::string description) {
        const std::string def = choices.at(size_t(Params{}.*member));
        desc_.paramEnum(name, def, choices, std::move(description));
        readers_.push_back([member, name, choices](Params& p, const ParamValues& v) {
            const std::string& s = v.getString(name);
            for (size_t i = 0; i < choices.size(); ++i)
                if (choices[i] == s) p.*member = E(i);
        });
    }
    /// A float parameter read into a double member (getDouble), for a value used in double
    /// arithmetic: its default and value stay as written instead of rounded to float (0.6 and
    /// double(0.6f) differ).
    void param(std::string name, double Params::*member, double min, double max,
               std::string description) {
        desc_.paramFloat(name, Params{}.*member, min, max, std::move(description));
        readers_.push_back(
            [member, name](Params& p, const ParamValues& v) { p.*member = v.getDouble(name); });
    }

    /// A float parameter as `param`, declared with the shortest decimal that reads back as the
    /// member's float: 0.2f is declared 0.2, as written in the struct, not 0.20000000298023224
    /// (as `kestrel passes --json` shows it). The values read are the same floats.
    void paramDecimal(std::string name, float Params::*member, double min, double max,
                      std::string description) {
        param(name, member, min, max, std::move(description));
        char text[32];
        const auto end = std::to_chars(text, text + sizeof text, Params{}.*member).ptr;
        double decimal = 0;
        std::from_chars(text, end, decimal);  // not strtod: no locale
        desc_.params.back().defaultValue = decimal;
    }
    /// PassDesc::fuseOn by handle: passes of this type may run fused when these inputs of each
    /// come from the same outputs.
    void fuseOn(std::initializer_list<const InputPort*> inputs,
                PassDesc::FusedOutputs outputs = PassDesc::FusedOutputs::Same) {
        std::vector<std::string> names;
        for (const InputPort* p : inputs) names.push_back(p->name);
        desc_.fuseOn(std::move(names), outputs);
    }
    /// A 64-bit integer parameter (sizes in pixels or bytes, beyond int's range).
    void param(std::string name, int64_t Params::*member, int64_t min, int64_t max,
               std::string description) {
        desc_.paramInt(name, Params{}.*member, min, max, std::move(description));
        readers_.push_back(
            [member, name](Params& p, const ParamValues& v) { p.*member = v.getInt(name); });
    }
    /// An enum parameter read as its choice's name, for a pass that passes the name on (a
    /// compression named to a library, a value quoted in messages).
    void param(std::string name, std::string Params::*member, std::vector<std::string> choices,
               std::string description) {
        desc_.paramEnum(name, Params{}.*member, std::move(choices), std::move(description));
        readers_.push_back(
            [member, name](Params& p, const ParamValues& v) { p.*member = v.getString(name); });
    }
    /// A sink (PassDesc::sink): writes outside the graph, so it is always live.
    void declareSink() { desc_.sink = true; }

private:
    PassDesc desc_;
    std::vector<std::function<void(Params&, const ParamValues&)>> readers_;
};

}  // namespace kestrel
