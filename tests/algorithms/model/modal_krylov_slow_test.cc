// The Krylov modal solver against the dense one on a 100-element shaft
// (808 states: the dense solver alone takes about 10 s; label slow).
#include <gtest/gtest.h>

#include "generated_rotor.h"
#include "modal_krylov_check.h"

namespace ambdiag {
namespace {

using testing::expect_same_modes;

TEST(ModalKrylov, MatchesDenseOnHundredElementShaft) {
  expect_same_modes(testing::generated_rotor(100), 3000.0, 2500.0);
}

}  // namespace
}  // namespace ambdiag
