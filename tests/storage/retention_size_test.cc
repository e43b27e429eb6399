// The file stays bounded under steady streaming with a size policy (the
// short version; retention_size_slow_test.cc streams 2.4 GB).
#include "retention_size.h"

namespace ambdiag::storage {
namespace {

TEST(RetentionSize, TheFileStaysBoundedUnderSteadyStreamingWithASizePolicy) {
  expect_bounded(stream_with_retention(SteadyStream{}));
}

}  // namespace
}  // namespace ambdiag::storage
