#include "engine/search/random_stream.h"

#include <locale>
#include <sstream>
#include <stdexcept>

namespace springfit {

double RandomStream::Uniform() {
  // The top 53 bits as an integer, times 2^-53: exactly representable, never 1.
  return static_cast<double>(engine_() >> 11) * 0x1.0p-53;
}

std::uint64_t RandomStream::Below(std::uint64_t n) {
  if (n == 0) throw std::invalid_argument("RandomStream::Below: n must be >= 1");
  // Reject the lowest 2^64 mod n values, so the remaining range is a multiple of n and
  // x mod n is exactly uniform.
  const std::uint64_t threshold = (0 - n) % n;
  std::uint64_t x = engine_();
  while (x < threshold) x = engine_();
  return x % n;
}

std::string RandomStream::SaveState() const {
  std::ostringstream out;
  out.imbue(std::locale::classic());
  out << engine_;
  return out.str();
}

void RandomStream::RestoreState(const std::string& state) {
  std::istringstream in(state);
  in.imbue(std::locale::classic());
  std::mt19937_64 engine;
  in >> engine;
  if (in.fail()) throw std::invalid_argument("RandomStream::RestoreState: not a saved state");
  engine_ = engine;
}

}  // namespace springfit
