#include "engine/probe_fit/spring_sensitivities.h"

#include <algorithm>

#include "engine/search/random_stream.h"

namespace springfit::response {
namespace {

// Right-hand sides solved in one call between stop checks.
constexpr Eigen::Index kSolveChunk = 64;

}  // namespace

SpringSensitivities::SpringSensitivities(const Vector& scale, int genes, Interruption* interruption,
                                         WorkerPool* pool)
    : interruption_(interruption), pool_(pool), scale_(scale), genes_(genes) {}

double SpringSensitivities::ResidualNorm2() const {
  double sum = 0.0;
  for (const Part& part : parts_) sum += part.residual.squaredNorm();
  return sum;
}

Vector SpringSensitivities::Residuals() const {
  Eigen::Index size = 0;
  for (const Part& part : parts_) size += part.residual.size();
  Vector all(size);
  Eigen::Index at = 0;
  for (const Part& part : parts_) {
    all.segment(at, part.residual.size()) = part.residual.reshaped();
    at += part.residual.size();
  }
  return all;
}

Vector SpringSensitivities::Gradient() const {
  return Sum([&](std::size_t i) {
    Matrix z = parts_[i].residual;
    SolveColumns(i, z);
    return Vector(-ColumnProducts(parts_[i], z));  // (evaluated before the temporary goes)
  });
}

Vector SpringSensitivities::NormalProduct(const Vector& v) const {
  const Vector sv = v.cwiseProduct(scale_);
  return Sum([&](std::size_t i) {
    const Part& part = parts_[i];
    const Eigen::Index count = part.residual.cols();
    Matrix y = Matrix::Zero(part.residual.rows(), count);
    for (Eigen::Index j = 0; j < count; ++j) {
      double* column = y.col(j).data();
      for (int e = 0; e < genes_; ++e) {
        const double a = part.elongation(e, j) * sv[e];
        if (a != 0.0) part.columns[static_cast<std::size_t>(e)].AddTo(a, column);
      }
    }
    SolveColumns(i, y);
    SolveColumns(i, y);
    return ColumnProducts(part, y);
  });
}

Vector SpringSensitivities::NormalDiagonal(int samples, std::uint64_t seed) const {
  const Vector scale2 = scale_.cwiseAbs2();
  return Sum([&](std::size_t i) {
    const Part& part = parts_[i];
    const auto n = part.residual.rows();
    RandomStream random(seed * 1000003u + part.key);
    Matrix z(n, samples);
    for (int c = 0; c < samples; ++c)
      for (Eigen::Index r = 0; r < n; ++r) z(r, c) = random.Uniform() < 0.5 ? -1.0 : 1.0;
    SolveColumns(i, z);
    Vector diagonal(genes_);
    for (int e = 0; e < genes_; ++e) {
      double compliance2 = 0.0;
      for (int c = 0; c < samples; ++c) {
        const double t = part.columns[static_cast<std::size_t>(e)].Dot(z.col(c).data());
        compliance2 += t * t;
      }
      diagonal[e] = scale2[e] * part.elongation.row(e).squaredNorm() * compliance2 / samples;
    }
    return diagonal;
  });
}

Vector SpringSensitivities::ColumnProducts(const Part& part, const Matrix& z) const {
  Vector out = Vector::Zero(genes_);
  for (Eigen::Index j = 0; j < z.cols(); ++j) {
    const double* column = z.col(j).data();
    for (int e = 0; e < genes_; ++e) {
      const double a = part.elongation(e, j);
      if (a != 0.0) out[e] += a * part.columns[static_cast<std::size_t>(e)].Dot(column);
    }
  }
  return out.cwiseProduct(scale_);
}

void SpringSensitivities::SolveColumns(std::size_t part, Matrix& b) const {
  for (Eigen::Index first = 0; first < b.cols(); first += kSolveChunk) {
    ThrowIfInterrupted(interruption_);
    const Eigen::Index count = std::min(kSolveChunk, b.cols() - first);
    Matrix chunk = b.middleCols(first, count);
    Solve(part, chunk);
    b.middleCols(first, count) = chunk;
  }
}

void SpringSensitivities::Run(const std::function<void(std::size_t)>& f) const {
  RunSlots(
      pool_, static_cast<int>(parts_.size()), [&](int slot) { f(static_cast<std::size_t>(slot)); },
      [this] {
        if (interruption_) interruption_->Check();
      });
  ThrowIfInterrupted(interruption_);
}

Vector SpringSensitivities::Sum(const std::function<Vector(std::size_t)>& f) const {
  std::vector<Vector> each(parts_.size());
  Run([&](std::size_t i) { each[i] = f(i); });
  Vector total = Vector::Zero(genes_);
  for (const Vector& v : each) total += v;
  return total;
}

}  // namespace springfit::response
