// VOXVIS_ASSERT (voxvis/assert.h): on in Debug and sanitizer builds, where a
// failed invariant aborts naming itself; compiled out of Release, where its
// condition is not even evaluated.
#include <gtest/gtest.h>

#include "voxvis/assert.h"

namespace voxvis::test {
namespace {

TEST(Assert, AFailedInvariantAbortsNamingItWhereAssertsAreOn) {
#if defined(VOXVIS_ASSERTS)
  int ok = 0;
  VOXVIS_ASSERT(++ok == 1);  // Evaluated once, and holds.
  EXPECT_EQ(ok, 1);
  EXPECT_DEATH(VOXVIS_ASSERT(ok == 2), "invariant failed: ok == 2");
#else
  int evaluated = 0;
  VOXVIS_ASSERT(++evaluated > 5);  // Neither evaluated nor checked.
  EXPECT_EQ(evaluated, 0);
#endif
}

}  // namespace
}  // namespace voxvis::test
