// Items 0..count-1 through a TBB pipeline: work in parallel, results
// consumed one at a time in item order, so what the consumer builds does not
// depend on the thread count. Used where pages are encoded (the store build)
// and decoded (simplify) in parallel and written or added in order.
#pragma once

#include <atomic>
#include <cstddef>
#include <memory>
#include <vector>

#include <tbb/concurrent_queue.h>
#include <tbb/parallel_pipeline.h>

#include "core/status.h"

namespace raylod {

// `work(Token&, size_t item) -> Status` runs in parallel; `consume(Token&,
// size_t item) -> Status` runs serially in item order, on the same token.
// At most ntokens items are in flight, each with a Token of its own (default
// constructed once, then reused: its buffers keep their capacity). The first
// error in item order, from work or consume, stops the pipeline and is
// returned; no later item is consumed.
template <class Token, class Work, class Consume>
Status ordered_pipeline(size_t count, size_t ntokens, Work work, Consume consume) {
  struct Slot {
    Token token;
    size_t item = 0;
    Status status;
  };
  ntokens = ntokens ? ntokens : 1;
  std::vector<std::unique_ptr<Slot>> pool;
  tbb::concurrent_queue<Slot*> free_slots;
  for (size_t i = 0; i < ntokens; ++i) {
    pool.push_back(std::make_unique<Slot>());
    free_slots.push(pool.back().get());
  }
  size_t next = 0;
  Status failed;                  // the consuming stage's; the input stage reads `stop`
  std::atomic<bool> stop{false};
  tbb::parallel_pipeline(
      ntokens,
      tbb::make_filter<void, Slot*>(tbb::filter_mode::serial_in_order,
                                    [&](tbb::flow_control& fc) -> Slot* {
                                      Slot* s = nullptr;
                                      // ntokens bound the flight, so a slot is always free.
                                      if (next == count || stop || !free_slots.try_pop(s)) {
                                        fc.stop();
                                        return nullptr;
                                      }
                                      s->item = next++;
                                      return s;
                                    }) &
          tbb::make_filter<Slot*, Slot*>(tbb::filter_mode::parallel,
                                         [&](Slot* s) {
                                           s->status = work(s->token, s->item);
                                           return s;
                                         }) &
          tbb::make_filter<Slot*, void>(tbb::filter_mode::serial_in_order, [&](Slot* s) {
            if (failed.is_ok()) failed = s->status;
            if (failed.is_ok()) failed = consume(s->token, s->item);
            if (!failed.is_ok()) stop = true;
            free_slots.push(s);
          }));
  return failed;
}

}  // namespace raylod
