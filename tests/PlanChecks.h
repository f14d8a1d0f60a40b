#pragma once
// Checks on a compiled graph's memory plan, shared by the engine and the shipped-graph tests.
#include <gtest/gtest.h>
#include <kestrel/Compiler.h>
#include <kestrel/Format.h>

namespace testutil {

/// Every transient resource in history memory lies in its planes' idle window: after last
/// frame's value was last read, and before this frame's is written (two buffers: to the end of
/// the frame). Only a resource the history is written over in place, holding all of its planes
/// in channel order, may reach the writing step. No two resources alive at the same time share
/// a history plane, and none has transient planes besides.
inline void expectHistoryLentOnlyWhileIdle(const kestrel::CompiledGraph& g) {
    const auto& res = g.resources();
    for (size_t i = 0; i < res.size(); ++i) {
        const auto& r = res[i];
        if (r.historyPlanes.empty()) continue;
        EXPECT_TRUE(r.planes.empty()) << r.producer;
        EXPECT_FALSE(r.marked || r.history) << r.producer;
        for (size_t c = 0; c < r.historyPlanes.size(); ++c) {
            const kestrel::HistoryPlane& hp = r.historyPlanes[c];
            const kestrel::ResourceInfo& h = res[size_t(hp.resource)];
            ASSERT_TRUE(h.history) << r.producer;
            EXPECT_GT(r.firstUse, h.lastHistoryRead) << r.producer << " in " << h.producer;
            if (h.doubleBuffered || r.lastUse < h.firstUse) continue;
            // Reaches the step writing h: only as the input h is written over in place.
            EXPECT_EQ(r.lastUse, h.firstUse) << r.producer << " in " << h.producer;
            EXPECT_EQ(r.historyPlanes.size(), size_t(kestrel::channelCount(h.format)));
            EXPECT_EQ(hp.channel, int(c)) << r.producer << " in " << h.producer;
            EXPECT_EQ(r.format, h.format) << r.producer << " in " << h.producer;
        }
        for (size_t j = i + 1; j < res.size(); ++j) {
            if (r.firstUse > res[j].lastUse || res[j].firstUse > r.lastUse) continue;
            for (const auto& a : r.historyPlanes)
                for (const auto& b : res[j].historyPlanes)
                    EXPECT_FALSE(a == b) << r.producer << " and " << res[j].producer;
        }
    }
}

}  // namespace testutil
