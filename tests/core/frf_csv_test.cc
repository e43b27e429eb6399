#include <gtest/gtest.h>
TEST(Placeholder, frf_csv) {}
