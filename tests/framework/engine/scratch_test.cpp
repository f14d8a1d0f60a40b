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

}  // namespace
}  // namespace kestrel
