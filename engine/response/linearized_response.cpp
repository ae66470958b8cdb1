#include "engine/response/linearized_response.h"

#include <algorithm>
#include <cmath>

#include "engine/search/random_stream.h"

namespace springfit::response {
namespace {

// Right-hand sides solved in one call between stop checks.
constexpr Eigen::Index kSolveChunk = 64;

}  // namespace

LinearizedResponse::LinearizedResponse(const ProbeObjective& objective, const GeneSprings& springs,
                                       Interruption* interruption, WorkerPool* pool)
    : objective_(&objective), springs_(&springs), interruption_(interruption), pool_(pool) {}

bool LinearizedResponse::At(const std::vector<double>& weights) {
  const Problem& problem = objective_->problem();
  const ProbeBank& bank = objective_->bank();
  const SparseMatrix k = SpringRestStiffness(problem, weights);
  const std::vector<std::size_t>& used = objective_->fitted_supports();
  parts_.clear();
  for (std::size_t s : used) {
    Part part{s, SupportSystem(problem.dimension(), bank.supports[s].constrained), {}, {}, {}, {}};
    for (std::size_t p = 0; p < bank.probes.size(); ++p)
      if (objective_->weight()[p] > 0.0 && bank.probes[p].support == static_cast<int>(s))
        part.probes.push_back(static_cast<int>(p));
    parts_.push_back(std::move(part));
  }
  std::vector<char> held(parts_.size(), 0);
  Run([&](std::size_t i) {
    Part& part = parts_[i];
    if (!(held[i] = part.system.Factorize(k))) return;
    part.columns = FreeColumns(*springs_, part.system);
    const auto count = static_cast<Eigen::Index>(part.probes.size());
    const int n = part.system.free_dofs();
    Matrix u(n, count);
    for (Eigen::Index j = 0; j < count; ++j) {
      const Probe& probe = bank.probes[static_cast<std::size_t>(part.probes[j])];
      u.col(j) = part.system.RightHandSide(probe.force, probe.prescribed);
    }
    SolveColumns(part.system, u);
    part.residual.resize(n, count);
    part.elongation.resize(springs_->size(), count);
    for (Eigen::Index j = 0; j < count; ++j) {
      const std::size_t p = static_cast<std::size_t>(part.probes[j]);
      const Probe& probe = bank.probes[p];
      const double root = std::sqrt(objective_->weight()[p]);
      const Vector full = part.system.Scatter(u.col(j), probe.prescribed);
      part.residual.col(j) = root * (u.col(j) - part.system.Gather(probe.reference));
      part.elongation.col(j) = root * Elongations(*springs_, full);
    }
  });
  return std::find(held.begin(), held.end(), 0) == held.end();
}

FactorizedOn LinearizedResponse::Factorized() const {
  return [this](std::size_t support) -> const SupportSystem* {
    for (const Part& part : parts_)
      if (part.support == support) return &part.system;
    return nullptr;
  };
}

double LinearizedResponse::ResidualNorm2() const {
  double sum = 0.0;
  for (const Part& part : parts_) sum += part.residual.squaredNorm();
  return sum;
}

Vector LinearizedResponse::Residuals() const {
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

Vector LinearizedResponse::Gradient() const {
  return Sum([&](const Part& part) {
    Matrix z = part.residual;
    SolveColumns(part.system, z);
    return Vector(-ColumnProducts(part, z));  // (evaluated before the temporary goes)
  });
}

Vector LinearizedResponse::NormalProduct(const Vector& v) const {
  const Vector sv = v.cwiseProduct(objective_->scale());
  return Sum([&](const Part& part) {
    const auto count = static_cast<Eigen::Index>(part.probes.size());
    Matrix y = Matrix::Zero(part.system.free_dofs(), count);
    for (Eigen::Index j = 0; j < count; ++j) {
      double* column = y.col(j).data();
      for (int e = 0; e < springs_->size(); ++e) {
        const double a = part.elongation(e, j) * sv[e];
        if (a != 0.0) part.columns[static_cast<std::size_t>(e)].AddTo(a, column);
      }
    }
    SolveColumns(part.system, y);
    SolveColumns(part.system, y);
    return ColumnProducts(part, y);
  });
}

Vector LinearizedResponse::NormalDiagonal(int samples, std::uint64_t seed) const {
  const Vector scale2 = objective_->scale().cwiseAbs2();
  return Sum([&](const Part& part) {
    const int n = part.system.free_dofs();
    RandomStream random(seed * 1000003u + part.support);
    Matrix z(n, samples);
    for (int c = 0; c < samples; ++c)
      for (int i = 0; i < n; ++i) z(i, c) = random.Uniform() < 0.5 ? -1.0 : 1.0;
    SolveColumns(part.system, z);
    Vector diagonal(springs_->size());
    for (int e = 0; e < springs_->size(); ++e) {
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

Vector LinearizedResponse::ColumnProducts(const Part& part, const Matrix& z) const {
  Vector out = Vector::Zero(springs_->size());
  for (Eigen::Index j = 0; j < z.cols(); ++j) {
    const double* column = z.col(j).data();
    for (int e = 0; e < springs_->size(); ++e) {
      const double a = part.elongation(e, j);
      if (a != 0.0) out[e] += a * part.columns[static_cast<std::size_t>(e)].Dot(column);
    }
  }
  return out.cwiseProduct(objective_->scale());
}

void LinearizedResponse::SolveColumns(const SupportSystem& system, Matrix& b) const {
  for (Eigen::Index first = 0; first < b.cols(); first += kSolveChunk) {
    ThrowIfInterrupted(interruption_);
    const Eigen::Index count = std::min(kSolveChunk, b.cols() - first);
    Matrix chunk = b.middleCols(first, count);
    system.SolveColumns(chunk);
    b.middleCols(first, count) = chunk;
  }
}

void LinearizedResponse::Run(const std::function<void(std::size_t)>& f) const {
  RunSlots(
      pool_, static_cast<int>(parts_.size()), [&](int slot) { f(static_cast<std::size_t>(slot)); },
      [this] {
        if (interruption_) interruption_->Check();
      });
  ThrowIfInterrupted(interruption_);
}

Vector LinearizedResponse::Sum(const std::function<Vector(const Part&)>& f) const {
  std::vector<Vector> each(parts_.size());
  Run([&](std::size_t i) { each[i] = f(parts_[i]); });
  Vector total = Vector::Zero(springs_->size());
  for (const Vector& v : each) total += v;
  return total;
}

}  // namespace springfit::response
