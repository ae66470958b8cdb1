#include "server/jobs/checkpoint_codec.h"

#include <cstdint>
#include <cstring>
#include <stdexcept>
#include <type_traits>

#include "engine/api/checkpoint.h"
#include "proto/search_codec.h"
#include "server/version.h"

namespace springfit::server {
namespace {

constexpr char kMagic[8] = {'S', 'F', 'C', 'K', 'P', 'T', '0', '4'};  // format version 4
constexpr std::uint32_t kByteOrderMark = 0x01020304;

class Writer {
 public:
  template <typename T>
  void Put(T value) {
    static_assert(std::is_trivially_copyable_v<T>);
    char bytes[sizeof(T)];
    std::memcpy(bytes, &value, sizeof(T));
    out_.append(bytes, sizeof(T));
  }
  void PutString(const std::string& s) {
    Put<std::uint64_t>(s.size());
    out_.append(s);
  }
  void PutGenome(const Genome& g) {
    Put<std::uint8_t>(g.empty() ? 0 : 1);
    if (!g.empty()) PutString(PackGenome(g));
  }
  void PutFitness(const Fitness& f) {
    Put(f.cost);
    Put(f.normalized_error);
    Put<std::int32_t>(f.mechanism_modes);
    Put<std::uint8_t>(f.mechanism ? 1 : 0);
    Put<std::uint8_t>(f.converged ? 1 : 0);
  }
  std::string Take() { return std::move(out_); }

 private:
  std::string out_;
};

class Reader {
 public:
  Reader(const std::string& bytes, int genes) : bytes_(bytes), genes_(genes) {}
  template <typename T>
  T Get() {
    Need(sizeof(T));
    T value;
    std::memcpy(&value, bytes_.data() + pos_, sizeof(T));
    pos_ += sizeof(T);
    return value;
  }
  std::string GetString() {
    const auto n = Get<std::uint64_t>();
    Need(n);
    std::string s = bytes_.substr(pos_, n);
    pos_ += n;
    return s;
  }
  Genome GetGenome() {
    if (Get<std::uint8_t>() == 0) return {};
    const std::string key = GetString();
    if (key.size() != (static_cast<std::size_t>(genes_) + 7) / 8)
      throw std::runtime_error("checkpoint: genome size");
    return UnpackGenome(key, genes_);
  }
  Fitness GetFitness() {
    Fitness f;
    f.cost = Get<double>();
    f.normalized_error = Get<double>();
    f.mechanism_modes = Get<std::int32_t>();
    f.mechanism = Get<std::uint8_t>() != 0;
    f.converged = Get<std::uint8_t>() != 0;
    return f;
  }
  // Element counts are checked against the bytes left, so a corrupt count cannot allocate.
  std::size_t GetCount(std::size_t min_bytes_each) {
    const auto n = Get<std::uint64_t>();
    if (min_bytes_each > 0 && n > (bytes_.size() - pos_) / min_bytes_each)
      throw std::runtime_error("checkpoint: count");
    return n;
  }
  bool AtEnd() const { return pos_ == bytes_.size(); }

 private:
  void Need(std::size_t n) const {
    if (n > bytes_.size() - pos_) throw std::runtime_error("checkpoint: truncated");
  }
  const std::string& bytes_;
  int genes_;
  std::size_t pos_ = 0;
};

}  // namespace

std::uint64_t OptionsFingerprint(const SearchOptions& options) {
  const std::string text = proto::SearchOptionsToJson(options).dump();
  std::uint64_t h = 14695981039346656037ULL;
  for (const unsigned char c : text) {
    h ^= c;
    h *= 1099511628211ULL;
  }
  return h;
}

std::string EncodeCheckpoint(const SearchState& s, int genes, std::uint64_t fingerprint) {
  Writer w;
  for (char c : kMagic) w.Put(c);
  w.Put(kByteOrderMark);
  w.PutString(kVersion);
  w.Put<std::uint64_t>(fingerprint);
  w.Put<std::int32_t>(genes);
  w.Put<std::int32_t>(s.generation);
  w.PutString(s.random_state);
  w.Put<std::uint64_t>(s.population.size());
  for (const Genome& g : s.population) w.PutGenome(g);
  w.Put<std::uint64_t>(s.fitness.size());
  for (const Fitness& f : s.fitness) w.PutFitness(f);
  w.PutGenome(s.best);
  w.PutFitness(s.best_fitness);
  w.Put<std::int32_t>(s.best_generation);
  w.Put<std::int32_t>(s.stall);
  w.PutGenome(s.local_optimum);
  w.Put<std::int64_t>(s.counters.evaluations);
  w.Put<std::int64_t>(s.counters.cache_hits);
  w.Put(s.elapsed_seconds);
  w.Put<std::uint64_t>(s.seeds.size());
  for (const Genome& g : s.seeds) w.PutGenome(g);
  w.Put(s.seeded_seconds);
  return w.Take();
}

SearchState DecodeCheckpoint(const std::string& bytes, int genes, std::uint64_t fingerprint) {
  Reader r(bytes, genes);
  for (char c : kMagic) {
    if (r.Get<char>() != c)
      throw std::runtime_error("checkpoint: not a springfit checkpoint of format version 4");
  }
  if (r.Get<std::uint32_t>() != kByteOrderMark)
    throw std::runtime_error("checkpoint: written on another byte order");
  const std::string version = r.GetString();
  if (version != kVersion) {
    throw std::runtime_error("checkpoint: written by springfitd " + version + ", this is " +
                             kVersion);
  }
  if (r.Get<std::uint64_t>() != fingerprint) {
    throw std::runtime_error(
        "checkpoint: written for other search options (the strategy's operators or defaults "
        "changed)");
  }
  if (r.Get<std::int32_t>() != genes)
    throw std::runtime_error("checkpoint: written for another number of genes");
  SearchState s;
  s.generation = r.Get<std::int32_t>();
  s.random_state = r.GetString();
  s.population.resize(r.GetCount(1));
  for (Genome& g : s.population) g = r.GetGenome();
  s.fitness.resize(r.GetCount(22));
  for (Fitness& f : s.fitness) f = r.GetFitness();
  s.best = r.GetGenome();
  s.best_fitness = r.GetFitness();
  s.best_generation = r.Get<std::int32_t>();
  s.stall = r.Get<std::int32_t>();
  s.local_optimum = r.GetGenome();
  s.counters.evaluations = r.Get<std::int64_t>();
  s.counters.cache_hits = r.Get<std::int64_t>();
  s.elapsed_seconds = r.Get<double>();
  s.seeds.resize(r.GetCount(1));
  for (Genome& g : s.seeds) g = r.GetGenome();
  s.seeded_seconds = r.Get<double>();
  if (!r.AtEnd()) throw std::runtime_error("checkpoint: trailing bytes");
  return s;
}

}  // namespace springfit::server
