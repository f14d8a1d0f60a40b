// Typed pass declarations (kestrel/Declare.h): the PassDesc derived from them, parameters read
// into the struct with the struct's defaults, and ports reached by handle in a compiled graph
// (the executor by index, a handle's port found even where another port has the same name).
#include <gtest/gtest.h>

#include <string>
#include <variant>

#include "TestPasses.h"

namespace kestrel::enginetest {
namespace {

enum class Mode { Add, Scale };

/// out = in + offset (Add) or in * offset (Scale); `bias` is an optional input added after, and
/// an output named like it (`bias`) echoes it, so a lookup by name could confuse the two.
class TypedPass final : public Pass {
public:
    struct Params {
        float offset = 2.5f;
        int repeat = 1;
        bool enabled = true;
        Mode mode = Mode::Add;
    };
    struct Declaration : kestrel::Declaration<Params> {
        Declaration() : kestrel::Declaration<Params>("Typed", "typed declaration under test") {
            in = input("in", Format::Float, "the value");
            bias = optionalInput("bias", Format::Float, "added last");
            out = output("out", Format::Float, "the result", &in);
            biasOut = output("bias", Format::Float, "the bias, echoed");
            param("offset", &Params::offset, -10.0, 10.0, "operand");
            param("repeat", &Params::repeat, 1, 4, "times the operation is applied");
            param("enabled", &Params::enabled, "false: out = in");
            param("mode", &Params::mode, {"add", "scale"}, "operation");
        }
        InputPort in, bias;
        OutputPort out, biasOut;
    };
    static const Declaration& declaration() {
        static const Declaration d;
        return d;
    }
    static PassDesc describe() { return declaration().desc(); }
    explicit TypedPass(const ParamValues& p) : p_(declaration().read(p)) {}
    void resolve(ResolveContext& rc) override {
        const Declaration& d = declaration();
        if (!p_.enabled) rc.forward(d.out, d.in);
        if (!rc.isBound(d.bias)) rc.setAbsent(d.biasOut, "no bias");
    }
    void execute(FrameContext&, PassIO& io) override {
        const Declaration& d = declaration();
        const ImageView& in = io.input(d.in);
        const ImageView* bias = io.has(d.bias) ? &io.input(d.bias) : nullptr;
        if (io.has(d.out))
            for (size_t i = 0; i < in.pixels(); ++i) {
                float v = in.channel(0)[i];
                for (int k = 0; k < p_.repeat; ++k)
                    v = p_.mode == Mode::Add ? v + p_.offset : v * p_.offset;
                io.output(d.out).channel(0)[i] = v + (bias ? bias->channel(0)[i] : 0.f);
            }
        if (bias && io.has(d.biasOut))
            for (size_t i = 0; i < in.pixels(); ++i)
                io.output(d.biasOut).channel(0)[i] = bias->channel(0)[i];
    }

private:
    Params p_;
};

float run(const std::string& json, const std::string& output) {
    Registry r = testRegistry();
    r.add<TypedPass>();
    auto g = compileText(json, r);
    Parallel par(1);
    Executor ex(*g, par, {}, Extent{2, 2});
    ex.runFrame(1);
    return ex.output(output).at(0, 1, 1);
}

/// Parameters declared as decimals, and inputs to fuse on, by handle.
struct DecimalParams {
    float alpha = 0.2f;
    float sigma = 0.6f;
};
struct FusingDeclaration : Declaration<DecimalParams> {
    FusingDeclaration() : Declaration<DecimalParams>("Fusing", "fuseOn and paramDecimal") {
        color = input("color", Format::Float3, "the signal");
        depth = input("depth", Format::Float, "geometry");
        id = optionalInput("objectId", Format::Int32, "geometry");
        out = output("color", Format::Float3, "the result");
        fuseOn({&depth, &id}, PassDesc::FusedOutputs::MayDiffer);
        paramDecimal("alpha", &DecimalParams::alpha, 0.0, 1.0, "as written");
        param("sigma", &DecimalParams::sigma, 0.0, 1.0, "the float's exact value");
    }
    InputPort color, depth, id;
    OutputPort out;
};

/// A double parameter: its default and its value reach the struct unrounded.
struct DoubleParams {
    double sigma = 0.6;
};
struct DoubleDeclaration : Declaration<DoubleParams> {
    DoubleDeclaration() : Declaration<DoubleParams>("Double", "double parameter under test") {
        param("sigma", &DoubleParams::sigma, 1e-4, 1e6, "a sigma used in double arithmetic");
    }
};

}  // namespace

TEST(Declaration, DecimalDefaultsAreAsWrittenAndReadBackAsTheFloat) {
    const FusingDeclaration decl;
    const PassDesc& d = decl.desc();
    EXPECT_EQ(std::get<double>(d.findParam("alpha")->defaultValue), 0.2);
    EXPECT_EQ(std::get<double>(d.findParam("sigma")->defaultValue), double(0.6f));
    ParamValues values({{"alpha", 0.2}, {"sigma", 0.6}});
    EXPECT_EQ(decl.read(values).alpha, 0.2f);
    EXPECT_EQ(decl.read(values).sigma, 0.6f);
}

TEST(Declaration, FusesOnInputsByHandle) {
    const FusingDeclaration decl;
    const PassDesc& d = decl.desc();
    EXPECT_EQ(d.fusedInputs, (std::vector<std::string>{"depth", "objectId"}));
    EXPECT_TRUE(d.fusedOutputsMayDiffer);
    EXPECT_EQ(d.ports.size(), 4u);  // fuseOn declares no port
}

TEST(Declaration, DescribesPortsInOrderAndParametersWithTheStructsDefaults) {
    const PassDesc d = TypedPass::describe();
    const auto& decl = TypedPass::declaration();
    ASSERT_EQ(d.ports.size(), 4u);
    for (const auto* h : {&decl.in, &decl.bias}) EXPECT_EQ(d.ports[size_t(h->index)].name, h->name);
    EXPECT_EQ(d.ports[size_t(decl.out.index)].kind, PortKind::Output);
    EXPECT_EQ(d.ports[size_t(decl.biasOut.index)].name, "bias");
    EXPECT_TRUE(d.ports[size_t(decl.bias.index)].optional);
    EXPECT_EQ(d.ports[size_t(decl.out.index)].inPlaceOf, "in");
    EXPECT_EQ(std::get<double>(d.findParam("offset")->defaultValue), 2.5);
    EXPECT_EQ(std::get<int64_t>(d.findParam("repeat")->defaultValue), 1);
    EXPECT_EQ(std::get<bool>(d.findParam("enabled")->defaultValue), true);
    EXPECT_EQ(std::get<std::string>(d.findParam("mode")->defaultValue), "add");
}

TEST(Declaration, ParametersArriveAsTheStruct) {
    const std::string graph = R"({"kestrel": 1, "passes": [{"name": "c", "type": "Const",
        "params": {"value": 3}}, {"name": "t", "type": "Typed", "params": PARAMS}],
        "edges": [{"from": "c.out", "to": "t.in"}], "outputs": ["t.out"]})";
    auto with = [&](const std::string& params) {
        std::string g = graph;
        g.replace(g.find("PARAMS"), 6, params);
        return run(g, "t.out");
    };
    EXPECT_FLOAT_EQ(with("{}"), 5.5f);  // 3 + 2.5, the declared defaults
    EXPECT_FLOAT_EQ(with(R"({"offset": 1, "repeat": 3})"), 6.f);
    EXPECT_FLOAT_EQ(with(R"({"offset": 2, "repeat": 2, "mode": "scale"})"), 12.f);
    EXPECT_FLOAT_EQ(with(R"({"enabled": false})"), 3.f);  // forwarded by handle
}

TEST(Declaration, DoubleParametersKeepTheirDoubleValue) {
    const DoubleDeclaration d;
    const ParamDesc* sigma = d.desc().findParam("sigma");
    ASSERT_NE(sigma, nullptr);
    EXPECT_EQ(sigma->type, ParamType::Float);
    EXPECT_EQ(std::get<double>(sigma->defaultValue), 0.6);  // not double(0.6f)
    EXPECT_EQ(d.read(ParamValues({{"sigma", 0.6}})).sigma, 0.6);
    EXPECT_EQ(d.read(ParamValues({{"sigma", int64_t(2)}})).sigma, 2.0);
}

TEST(Declaration, HandlesReachTheirOwnPortWhereNamesRepeat) {
    // The input `bias` and the output `bias` share a name; each handle reaches its own.
    const float out = run(R"({"kestrel": 1, "passes": [{"name": "c", "type": "Const",
        "params": {"value": 3}}, {"name": "b", "type": "Const", "params": {"value": 10}},
        {"name": "t", "type": "Typed"}],
        "edges": [{"from": "c.out", "to": "t.in"}, {"from": "b.out", "to": "t.bias"}],
        "outputs": ["t.out", "t.bias"]})",
                          "t.out");
    EXPECT_FLOAT_EQ(out, 15.5f);
    EXPECT_FLOAT_EQ(run(R"({"kestrel": 1, "passes": [{"name": "c", "type": "Const"},
        {"name": "b", "type": "Const", "params": {"value": 10}}, {"name": "t", "type": "Typed"}],
        "edges": [{"from": "c.out", "to": "t.in"}, {"from": "b.out", "to": "t.bias"}],
        "outputs": ["t.bias"]})",
                        "t.bias"),
                    10.f);
}

namespace {
struct WideParams {
    int64_t pixels = int64_t(1) << 33;  // beyond int
    std::string codec = "zip";
};
struct WideDeclaration : Declaration<WideParams> {
    WideDeclaration() : Declaration<WideParams>("Wide", "int64 and enum-as-name parameters") {
        param("pixels", &WideParams::pixels, 1, int64_t(1) << 40, "a size");
        param("codec", &WideParams::codec, {"none", "zip", "piz"}, "a name passed on");
        declareSink();
    }
};
}  // namespace

TEST(Declaration, Int64AndEnumNameParameters) {
    const WideDeclaration d;
    const ParamDesc* pixels = d.desc().findParam("pixels");
    const ParamDesc* codec = d.desc().findParam("codec");
    ASSERT_TRUE(pixels && codec);
    EXPECT_TRUE(d.desc().sink);
    EXPECT_FALSE(TypedPass::describe().sink);
    EXPECT_EQ(std::get<int64_t>(pixels->defaultValue), int64_t(1) << 33);
    EXPECT_EQ(pixels->max, double(int64_t(1) << 40));
    EXPECT_EQ(codec->type, ParamType::Enum);
    EXPECT_EQ(std::get<std::string>(codec->defaultValue), "zip");
    EXPECT_EQ(codec->choices, (std::vector<std::string>{"none", "zip", "piz"}));
    const WideParams p =
        d.read(ParamValues({{"pixels", int64_t(5) << 32}, {"codec", std::string("piz")}}));
    EXPECT_EQ(p.pixels, int64_t(5) << 32);
    EXPECT_EQ(p.codec, "piz");
}

}  // namespace kestrel::enginetest
