#include <gtest/gtest.h>
TEST(Placeholder, uff58) {}
