// Plugin loading: a good module registers usable types; every broken module is a clear
// kestrel::Error naming the file, never a crash. The test plugins are built by this folder's
// CMakeLists into test-only directories (never the real plugin directory).
#include <gtest/gtest.h>

#include <filesystem>
#include <fstream>
#include <string>

#include "TestPasses.h"

namespace kestrel::enginetest {
namespace {

namespace fs = std::filesystem;

/// The Error load() throws for `module`, checked to name the file.
std::string loadError(const fs::path& module, Registry& registry, PluginLoader& loader) {
    try {
        loader.load(module, registry);
    } catch (const GraphError& e) {
        ADD_FAILURE() << "a plugin problem is not a graph error: " << e.what();
        return e.what();
    } catch (const Error& e) {
        std::string m = e.what();
        EXPECT_NE(m.find(module.string()), std::string::npos) << "file not named: " << m;
        return m;
    }
    ADD_FAILURE() << module << " loaded without error";
    return {};
}

bool contains(const std::string& s, const std::string& part) {
    return s.find(part) != std::string::npos;
}

TEST(Plugin, GoodPluginLoadsAndItsTypeRunsInAGraph) {
    PluginLoader loader;  // declared first: outlives the registry and the graph
    Registry registry;
    loader.load(KESTREL_TEST_PLUGIN_GOOD, registry);
    ASSERT_EQ(loader.loaded().size(), 1u);
    const PassType* t = registry.find("PluginFortyTwo");
    ASSERT_NE(t, nullptr);
    EXPECT_EQ(t->module, std::string(KESTREL_TEST_PLUGIN_GOOD));

    auto g = compileText(R"({"kestrel": 1, "passes": [{"name": "p", "type": "PluginFortyTwo"}],
        "outputs": ["p.out"]})",
                         registry);
    Parallel par(1);
    Executor ex(*g, par, {}, Extent{2, 2});
    ex.runFrame(1);
    EXPECT_EQ(ex.output("p.out").at(0, 1, 1), 42.f);
}

TEST(Plugin, LoadDirectoriesFindsModulesAndSkipsMissingDirectories) {
    PluginLoader loader;
    Registry registry;
    fs::path dir = fs::path(KESTREL_TEST_PLUGIN_GOOD).parent_path();
    loader.loadDirectories({"/nonexistent/kestrel/plugins", dir}, registry);
    EXPECT_NE(registry.find("PluginFortyTwo"), nullptr);
    EXPECT_EQ(loader.loaded().size(), 1u);
}

TEST(Plugin, MissingEntryPoint) {
    PluginLoader loader;
    Registry registry;
    std::string m = loadError(KESTREL_TEST_PLUGIN_NO_ENTRY, registry, loader);
    EXPECT_TRUE(contains(m, "missing entry point kestrelPluginAbiVersion")) << m;
    EXPECT_TRUE(loader.loaded().empty());
}

TEST(Plugin, WrongAbiVersion) {
    PluginLoader loader;
    Registry registry;
    // The module's kestrelRegisterPlugin aborts: reaching it would kill the test.
    std::string m = loadError(KESTREL_TEST_PLUGIN_BAD_ABI, registry, loader);
    EXPECT_TRUE(contains(m, "ABI version 999")) << m;
    EXPECT_TRUE(contains(m, "version " + std::to_string(KESTREL_PLUGIN_ABI_VERSION))) << m;
    EXPECT_TRUE(registry.all().empty());
}

TEST(Plugin, DuplicateTypeAcrossTwoPlugins) {
    PluginLoader loader;
    Registry registry;
    loader.load(KESTREL_TEST_PLUGIN_GOOD, registry);
    std::string m = loadError(KESTREL_TEST_PLUGIN_DUPLICATE, registry, loader);
    EXPECT_TRUE(contains(m, "duplicate pass type 'PluginFortyTwo'")) << m;
    // Both modules are named: the one that registered it first, and the newcomer.
    EXPECT_TRUE(contains(m, std::string("registered by ") + KESTREL_TEST_PLUGIN_GOOD)) << m;
    // The first registration stays intact and usable.
    ASSERT_NE(registry.find("PluginFortyTwo"), nullptr);
    EXPECT_EQ(registry.find("PluginFortyTwo")->module, std::string(KESTREL_TEST_PLUGIN_GOOD));
    EXPECT_EQ(registry.find("PluginFortyTwo")->desc.description, "writes 42");
}

TEST(Plugin, DuplicateOfATypeRegisteredInCode) {
    PluginLoader loader;
    Registry registry = testRegistry();
    registry.add(PassDesc("PluginFortyTwo", "in code"),
                 [](const ParamValues& p) { return std::make_unique<ConstPass>(p); });
    std::string m = loadError(KESTREL_TEST_PLUGIN_GOOD, registry, loader);
    EXPECT_TRUE(contains(m, "built-in code")) << m;
}

// A helper module (kestrel_ocio.so, kestrel_oiio.so) is looked for beside the plugin folder; one
// that is not there is an error naming the file, and its entry points are null, never a crash.
TEST(Plugin, MissingHelperModuleIsNamedAndHasNoEntryPoints) {
    const HelperModule m = openHelperModule("kestrel_no_such_helper.so");
    EXPECT_EQ(m.handle, nullptr);
    EXPECT_NE(m.error.find("kestrel_no_such_helper.so"), std::string::npos) << m.error;
    EXPECT_EQ(m.symbol("anything"), nullptr);
    ASSERT_FALSE(defaultPluginDirectories().empty());
    EXPECT_EQ(m.path,
              defaultPluginDirectories().front().parent_path() / "kestrel_no_such_helper.so");
}

TEST(Plugin, NonLoadableFile) {
    fs::path dir = fs::path(::testing::TempDir()) / "kestrel_engine_plugin_test";
    fs::create_directories(dir);
    fs::path fake = dir / "x.so";
    std::ofstream(fake) << "this is not a shared library\n";
    PluginLoader loader;
    Registry registry;
    std::string m = loadError(fake, registry, loader);
    EXPECT_TRUE(contains(m, "cannot be loaded")) << m;
    // A directory scan reports the same file instead of skipping it silently.
    try {
        loader.loadDirectories({dir}, registry);
        ADD_FAILURE() << "scan accepted x.so";
    } catch (const Error& e) {
        EXPECT_TRUE(contains(e.what(), fake.string())) << e.what();
    }
    EXPECT_THROW(loader.load(dir / "absent.so", registry), Error);
    fs::remove_all(dir);
}

}  // namespace
}  // namespace kestrel::enginetest
