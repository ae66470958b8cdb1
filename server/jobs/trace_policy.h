// Which generations of a job's trace the store keeps (proto/RPC.md, "job.trace").
//
// Every generation below 10,000; beyond, every 10th below 100,000, every 100th below
// 1,000,000 and so on, plus every generation that improved the best genome and the last
// one. A job of any length stores at most about 10,000 rows per decade of generations and
// every point where its error curve moves. The rule depends only on the generation and on
// the search, so a resumed job stores exactly the rows of an uninterrupted one.
#pragma once

namespace springfit::server {

inline bool KeepTraceRow(int generation, bool improved, bool last) {
  if (improved || last) return true;
  int stride = 1;
  for (int bound = 10000; generation >= bound && bound <= 100000000; bound *= 10) stride *= 10;
  return generation % stride == 0;
}

}  // namespace springfit::server
