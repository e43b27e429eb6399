#include <gtest/gtest.h>
TEST(Placeholder, run_recording) {}
