// The progress display when stderr is not a terminal (a log file, CI): a
// line per tenth, and the closing line only if it says something new.
#include <gtest/gtest.h>
#include <unistd.h>

#include <cstdio>
#include <fstream>
#include <sstream>
#include <string>

#include "core/progress.h"
#include "test_tmp.h"

namespace raylod {
namespace {

// What `body` writes to stderr, through a file.
template <class F>
std::string stderr_of(F&& body) {
  raylod::test::ScratchDir dir("progress");
  const std::string path = (dir.path / "err.txt").string();
  std::fflush(stderr);
  const int saved = ::dup(2);
  std::FILE* f = std::fopen(path.c_str(), "w");
  ::dup2(::fileno(f), 2);
  body();
  std::fflush(stderr);
  ::dup2(saved, 2);
  ::close(saved);
  std::fclose(f);
  std::ifstream in(path);
  std::stringstream text;
  text << in.rdbuf();
  return text.str();
}

size_t count(const std::string& text, const std::string& what) {
  size_t n = 0;
  for (size_t at = text.find(what); at != std::string::npos; at = text.find(what, at + 1)) ++n;
  return n;
}

TEST(Progress, ARunThatEndsAtItsTotalSaysSoOnce) {
  Progress::set_enabled(true);
  const std::string out = stderr_of([] {
    Progress p("work", 20, "items");
    for (int i = 0; i < 20; ++i) p.advance(1);
    p.finish();
  });
  EXPECT_EQ(count(out, "work: 100% (20/20 items"), 1u) << out;
  EXPECT_GE(count(out, "work: "), 10u) << out;  // the tenths on the way
}

TEST(Progress, AClosingLineShowsWhereARunStoppedShort) {
  Progress::set_enabled(true);
  const std::string out = stderr_of([] {
    Progress p("work", 1000, "items");
    p.advance(998);  // 99.8%: the last tenth's line says 100%
    p.advance(1);    // not a new tenth: no line
    p.finish();      // the final count, on a line of its own
  });
  EXPECT_NE(out.find("(999/1000 items"), std::string::npos) << out;
  EXPECT_EQ(count(out, "(998/1000 items"), 1u) << out;
}

}  // namespace
}  // namespace raylod
