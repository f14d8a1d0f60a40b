// ScratchPool: concurrent leases get distinct plane sets; a returned set is reused.
#include <gtest/gtest.h>
#include <kestrel/Scratch.h>

#include <cstdint>

namespace kestrel {
namespace {

TEST(ScratchPool, ConcurrentLeasesNeverShareAndSetsAreReused) {
    float* first = nullptr;
    {
        auto a = ScratchPool::acquire(2, 1000);
        auto b = ScratchPool::acquire(2, 1000);
        EXPECT_NE(a[0], b[0]);
        EXPECT_NE(a[1], b[1]);
        EXPECT_NE(a[0], a[1]);
        EXPECT_EQ(reinterpret_cast<uintptr_t>(a[0]) % 64, 0u) << "64-byte aligned";
        a[0][999] = 1.f;  // the asked size is usable
        b[1][999] = 2.f;
        first = a[0];
    }
    const size_t held = ScratchPool::bytes();
    {
        auto c = ScratchPool::acquire(2, 500);  // smaller: the first free set, not a new one
        EXPECT_EQ(c[0], first);
    }
    EXPECT_EQ(ScratchPool::bytes(), held);
}

TEST(ScratchPool, EachPlaneGrowsOnlyToWhatItsLeasesAsk) {
    // Leases of different shapes share sets (A-Trous: a few band-sized planes; variance
    // estimation: more, smaller ones). The set holds, plane by plane, the largest size asked.
    const size_t before = ScratchPool::bytes();
    { auto a = ScratchPool::acquire(4, 100000); }  // the first free set: four large planes

    const size_t afterLarge = ScratchPool::bytes();
    {
        auto a = ScratchPool::acquire(10, 20000);  // the same set: six more, smaller planes
        a[9][19999] = 1.f;                         // the asked size is usable
    }
    const size_t grown = ScratchPool::bytes() - afterLarge;
    // Six more planes of 20000 values, not six (or ten) of 100000.
    EXPECT_LE(grown, 6 * 20000 * sizeof(float) + 6 * 4096) << "bytes added: " << grown;
    EXPECT_GE(ScratchPool::bytes(), before);
}

}  // namespace
}  // namespace kestrel
