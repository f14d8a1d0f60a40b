// ScratchPool: concurrent leases get distinct plane sets; a returned set is reused.
// ScratchArena: leases cut from idle planes first, the pool when those run out.
#include <gtest/gtest.h>
#include <kestrel/Image.h>
#include <kestrel/Scratch.h>

#include <algorithm>
#include <cstdint>
#include <vector>

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

bool inside(const float* p, size_t count, const float* plane, size_t planePixels) {
    return p >= plane && p + count <= plane + planePixels;
}

TEST(ScratchArena, LeasesComeFromIdlePlanesUntilTheyRunOut) {
    const size_t planePixels = 1000;
    PlaneStorage a = allocatePlane(planePixels), b = allocatePlane(planePixels);
    const std::vector<float*> idle = {a.get(), b.get()};
    auto inIdle = [&](const float* p, size_t n) {
        return inside(p, n, a.get(), planePixels) || inside(p, n, b.get(), planePixels);
    };
    ScratchArena arena(idle, planePixels);
    std::vector<const float*> seen;
    {
        // Pieces of 304 values (300 rounded to 64 bytes): three per plane, six in all.
        auto first = arena.acquire(3, 300);
        auto second = arena.acquire(3, 300);
        for (size_t i = 0; i < 3; ++i) {
            ASSERT_TRUE(inIdle(first[i], 300));
            ASSERT_TRUE(inIdle(second[i], 300));
            EXPECT_EQ(reinterpret_cast<uintptr_t>(first[i]) % 64, 0u) << "64-byte aligned";
            seen.push_back(first[i]);
            seen.push_back(second[i]);
        }
        for (size_t i = 0; i < seen.size(); ++i)  // disjoint pieces
            for (size_t j = i + 1; j < seen.size(); ++j)
                EXPECT_GE(std::max(seen[i], seen[j]) - std::min(seen[i], seen[j]), 300);
        auto third = arena.acquire(1, 300);  // none left: from the pool
        EXPECT_FALSE(inIdle(third[0], 300));
        EXPECT_EQ(arena.lentCount(), 2u);
    }
    auto again = arena.acquire(6, 300);  // every piece returned
    for (size_t i = 0; i < 6; ++i) EXPECT_TRUE(inIdle(again[i], 300));
    auto larger = arena.acquire(1, 400);  // more than a piece: from the pool
    EXPECT_FALSE(inIdle(larger[0], 400));
    EXPECT_EQ(arena.lentCount(), 3u);
}

TEST(ScratchArena, WithoutIdlePlanesEveryLeaseIsThePools) {
    ScratchArena arena({}, 1000);
    auto lease = arena.acquire(2, 100);
    lease[1][99] = 1.f;
    EXPECT_EQ(arena.lentCount(), 0u);
}

// Planes of every size, huge-page ones (4 MB and more: 2 MB aligned, advised MADV_HUGEPAGE)
// included: zero-filled, 64-byte aligned, staggered within a page (successive planes start at
// different offsets: see allocatePlane), writable to their last value, and freed by their own
// deleter (the sanitizer stage checks the free).
TEST(AllocatePlane, EverySizeIsZeroedAlignedStaggeredAndWritable) {
    for (size_t count : {size_t(1), size_t(1000), size_t(1) << 20, size_t(1920) * 1080 + 7}) {
        PlaneStorage a = allocatePlane(count), b = allocatePlane(count);
        for (const PlaneStorage* p : {&a, &b}) {
            EXPECT_EQ(reinterpret_cast<uintptr_t>(p->get()) % 64, 0u) << count;
            EXPECT_TRUE(std::all_of(p->get(), p->get() + count, [](float v) { return v == 0.f; }))
                << count;
            p->get()[count - 1] = 1.f;
        }
        EXPECT_NE(reinterpret_cast<uintptr_t>(a.get()) % 4096,
                  reinterpret_cast<uintptr_t>(b.get()) % 4096)
            << count << ": successive planes fall into different cache sets";
    }
}

}  // namespace
}  // namespace kestrel
