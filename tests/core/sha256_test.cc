// SHA-256 against the FIPS 180-4 examples (NIST CSRC "Examples with
// intermediate values", SHA256.pdf and SHA2_Additional.pdf).
#include "ambdiag/core/sha256.h"

#include <gtest/gtest.h>

#include <string>

namespace ambdiag {
namespace {

TEST(Sha256, OneBlockMessageAbc) {
  EXPECT_EQ(to_hex(sha256("abc")), "ba7816bf8f01cfea414140de5dae2223b00361a396177a9cb410ff61f20015ad");
}

TEST(Sha256, EmptyMessage) {
  EXPECT_EQ(to_hex(sha256("")), "e3b0c44298fc1c149afbf4c8996fb92427ae41e4649b934ca495991b7852b855");
}

TEST(Sha256, TwoBlockMessageOf448Bits) {
  // 56 bytes: the padding's 1 bit and length no longer fit the first block.
  EXPECT_EQ(to_hex(sha256("abcdbcdecdefdefgefghfghighijhijkijkljklmklmnlmnomnopnopq")),
            "248d6a61d20638b8e5c026930c3e6039a33ce45964ff2167f6ecedd419db06c1");
}

TEST(Sha256, OneMillionTimesAInPiecesOfAnySize) {
  const std::string expected = "cdc76e5c9914fb9281a1c7e284d73e67f1809a48a497200e046d39ccc7112cd0";
  EXPECT_EQ(to_hex(sha256(std::string(1000000, 'a'))), expected);
  // Cut into pieces of 1..97 bytes: the buffering between calls must not matter.
  Sha256 s;
  const std::string a(97, 'a');
  std::size_t left = 1000000, n = 1;
  while (left > 0) {
    const std::size_t take = std::min(left, n);
    s.update(a.data(), take);
    left -= take;
    n = n % 97 + 1;
  }
  EXPECT_EQ(to_hex(s.digest()), expected);
}

TEST(Sha256, ResetStartsAgain) {
  Sha256 s;
  s.update("something else");
  s.digest();
  s.reset();
  s.update("abc");
  EXPECT_EQ(s.digest(), sha256("abc"));
  EXPECT_NE(sha256("abd"), sha256("abc"));
}

}  // namespace
}  // namespace ambdiag
