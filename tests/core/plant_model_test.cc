#include <gtest/gtest.h>
TEST(Placeholder, plant_model) {}
