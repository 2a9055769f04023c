// numeric_diff A B: exit 0 when the two text files hold the same words and numbers within the
// cross-machine tolerance (numeric_text.hpp), else 1 with the first difference on stdout.
// For the script tests that compare a file generated on this machine with a stored one.
#include <cstdio>
#include <fstream>
#include <iterator>
#include <string>

#include "support/numeric_text.hpp"

int main(int argc, char** argv) {
  if (argc != 3) {
    std::fprintf(stderr, "usage: numeric_diff A B\n");
    return 2;
  }
  std::string text[2];
  for (int i = 0; i < 2; ++i) {
    std::ifstream f(argv[1 + i], std::ios::binary);
    if (!f) {
      std::fprintf(stderr, "numeric_diff: %s: cannot read\n", argv[1 + i]);
      return 2;
    }
    text[i].assign(std::istreambuf_iterator<char>(f), {});
  }
  const std::string d = cell_test::numeric_difference(text[0], text[1]);
  if (d.empty()) return 0;
  std::printf("%s\n", d.c_str());
  return 1;
}
