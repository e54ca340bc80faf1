#include "core/progress.h"

#include <unistd.h>

#include <cstdio>

namespace raylod {
namespace {
std::atomic<bool> g_enabled{true};
}

void Progress::set_enabled(bool enabled) { g_enabled = enabled; }

Progress::Progress(std::string label, uint64_t total, std::string unit)
    : label_(std::move(label)), unit_(std::move(unit)), total_(total),
      start_(std::chrono::steady_clock::now()), last_draw_(start_), tty_(isatty(STDERR_FILENO) != 0) {}

Progress::~Progress() { finish(); }

void Progress::advance(uint64_t n) {
  done_.fetch_add(n, std::memory_order_relaxed);
  draw(false);
}

void Progress::set(uint64_t done) {
  done_.store(done, std::memory_order_relaxed);
  draw(false);
}

void Progress::finish() {
  if (finished_) return;
  draw(true);
  finished_ = true;
}

void Progress::draw(bool final_line) {
  if (!g_enabled) return;
  auto now = std::chrono::steady_clock::now();
  std::unique_lock lock(mutex_, std::try_to_lock);
  if (!lock.owns_lock() && !final_line) return;
  if (!lock.owns_lock()) lock.lock();
  if (finished_) return;
  uint64_t done = done_.load(std::memory_order_relaxed);
  double seconds = std::chrono::duration<double>(now - start_).count();
  double frac = total_ ? std::min(1.0, double(done) / double(total_)) : 0.0;
  // Time left, from the mean rate so far (once something is done).
  char left[48] = "";
  if (total_ && done > 0 && done < total_)
    std::snprintf(left, sizeof left, ", %.0fs left", seconds * double(total_ - done) / double(done));
  if (tty_) {
    if (!final_line && now - last_draw_ < std::chrono::milliseconds(100)) return;
    char bar[31];
    int filled = int(frac * 30);
    for (int i = 0; i < 30; ++i) bar[i] = i < filled ? '#' : '.';
    bar[30] = 0;
    if (total_)
      std::fprintf(stderr, "\r%-12s [%s] %5.1f%% %llu/%llu %s %.1fs%s", label_.c_str(), bar, 100 * frac,
                   (unsigned long long)done, (unsigned long long)total_, unit_.c_str(), seconds, left);
    else
      std::fprintf(stderr, "\r%-12s %llu %s %.1fs", label_.c_str(), (unsigned long long)done, unit_.c_str(), seconds);
    if (final_line) std::fputc('\n', stderr);
  } else {
    int decile = int(frac * 10);
    bool due = final_line || decile > last_decile_ || now - last_draw_ > std::chrono::seconds(5);
    // The closing line only if it says something new: a run that ended on
    // its 100% line is not reported twice.
    if (!due || (final_line && done == printed_done_)) return;
    last_decile_ = decile;
    printed_done_ = done;
    if (total_)
      std::fprintf(stderr, "%s: %.0f%% (%llu/%llu %s, %.1fs%s)\n", label_.c_str(), 100 * frac,
                   (unsigned long long)done, (unsigned long long)total_, unit_.c_str(), seconds, left);
    else
      std::fprintf(stderr, "%s: %llu %s (%.1fs)\n", label_.c_str(), (unsigned long long)done, unit_.c_str(), seconds);
  }
  last_draw_ = now;
}

}  // namespace raylod
