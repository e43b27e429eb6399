// A driver for fuzz entry points when libFuzzer is not available (GCC
// builds): runs every file of the seed corpus, then N seeded mutations of
// them (byte flips, truncations, insertions, splices). A crash or sanitizer
// report fails the test; an InputError is the expected refusal.
#include <cstdint>
#include <cstdio>
#include <filesystem>
#include <fstream>
#include <iterator>
#include <random>
#include <string>
#include <vector>

extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, size_t size);

namespace {

std::string mutate(const std::string& in, const std::vector<std::string>& corpus, std::mt19937_64& rng) {
  std::string s = in;
  const int steps = 1 + static_cast<int>(rng() % 4);
  static const char* kTokens[] = {"NaN", "-1", "1e999", "\n", ",", "\"", "}", "]", "null", "0", "-", "e", ".",
                                  "    -1", "1e308", "inf", "\r\n"};
  for (int i = 0; i < steps; ++i) {
    const size_t pos = s.empty() ? 0 : rng() % s.size();
    switch (rng() % 6) {
      case 0:
        if (!s.empty()) s[pos] = static_cast<char>(rng() % 256);
        break;
      case 1:
        s.resize(pos);
        break;
      case 2:
        s.insert(pos, kTokens[rng() % std::size(kTokens)]);
        break;
      case 3:
        if (!s.empty()) s.erase(pos, 1 + rng() % 16);
        break;
      case 4: {
        const std::string& other = corpus[rng() % corpus.size()];
        if (!other.empty()) s.insert(pos, other.substr(rng() % other.size(), 1 + rng() % 64));
        break;
      }
      default:
        if (!s.empty()) s.insert(pos, s.substr(pos, 1 + rng() % 32));
        break;
    }
  }
  return s;
}

}  // namespace

int main(int argc, char** argv) {
  if (argc < 3) {
    std::fprintf(stderr, "usage: %s ITERATIONS CORPUS_DIR...\n", argv[0]);
    return 2;
  }
  const long iterations = std::stol(argv[1]);
  std::vector<std::string> corpus;
  for (int a = 2; a < argc; ++a) {
    for (const auto& e : std::filesystem::directory_iterator(argv[a])) {
      std::ifstream in(e.path(), std::ios::binary);
      corpus.emplace_back(std::istreambuf_iterator<char>(in), std::istreambuf_iterator<char>());
    }
  }
  if (corpus.empty()) {
    std::fprintf(stderr, "empty corpus\n");
    return 2;
  }
  for (const auto& c : corpus) LLVMFuzzerTestOneInput(reinterpret_cast<const uint8_t*>(c.data()), c.size());
  std::mt19937_64 rng(20261122);
  for (long i = 0; i < iterations; ++i) {
    const std::string s = mutate(corpus[i % corpus.size()], corpus, rng);
    LLVMFuzzerTestOneInput(reinterpret_cast<const uint8_t*>(s.data()), s.size());
  }
  std::printf("%zu seeds, %ld mutations: no crash\n", corpus.size(), iterations);
  return 0;
}
