#include "engine/fem/fem_model.h"

#include <cmath>
#include <limits>

#include <Eigen/Eigenvalues>

namespace springfit::fem {
namespace {

template <int D>
MatD<D> EdgeMatrix(const Vector& x, const std::array<int, D + 1>& nodes) {
  MatD<D> m;
  for (int a = 0; a < D; ++a)
    m.col(a) = x.segment<D>(D * nodes[a + 1]) - x.segment<D>(D * nodes[0]);
  return m;
}

template <int D>
void BuildElements(const Scene& scene, std::vector<Element<D>>& out) {
  const FemReference& fem = scene.reference.fem;
  const double thickness = D == 2 ? fem.thickness : 1.0;
  const double factorial = D == 2 ? 2.0 : 6.0;
  out.resize(fem.elements.size());
  for (std::size_t e = 0; e < fem.elements.size(); ++e) {
    Element<D>& el = out[e];
    for (int a = 0; a <= D; ++a) el.nodes[a] = fem.elements[e][a];
    const MatD<D> dm = EdgeMatrix<D>(scene.rest, el.nodes);
    const MatD<D> dm_inv = dm.inverse();
    // F = Ds Dm^-1, Ds's column a = x_{a+1} - x_0: node a+1's gradient is row a of Dm^-1,
    // node 0's the negative sum.
    el.gradients.template bottomRows<D>() = dm_inv;
    el.gradients.row(0) = -dm_inv.colwise().sum();
    el.volume = std::abs(dm.determinant()) / factorial * thickness;
    el.law = fem.element_material.empty() ? 0 : fem.element_material[e];
  }
}

}  // namespace

FemModel FemModel::Build(const Scene& scene) {
  FemModel m;
  const FemReference& fem = scene.reference.fem;
  m.dimension_ = scene.dimension;
  m.node_count_ = scene.node_count();
  m.rest_ = scene.rest;
  for (const Material& material : fem.materials) {
    if (material.model != MaterialModel::kLinear) m.linear_ = false;
    if (m.dimension_ == 2) {
      m.laws2_.emplace_back(material, fem.plane);
    } else {
      m.laws3_.emplace_back(material, fem.plane);
    }
  }
  if (m.dimension_ == 2) {
    BuildElements<2>(scene, m.elements2_);
  } else {
    BuildElements<3>(scene, m.elements3_);
  }
  return m;
}

double FemModel::Jacobian(int e, const Vector& u) const {
  // det F = det(I + H), from the element's own nodes (no deformed copy of the whole mesh).
  if (dimension_ == 2)
    return (MatD<2>::Identity() + DisplacementGradient(elements2_[e], u)).determinant();
  return (MatD<3>::Identity() + DisplacementGradient(elements3_[e], u)).determinant();
}

int FemModel::FirstInvertedElement(const Vector& u) const {
  for (int e = 0; e < element_count(); ++e) {
    if (!(Jacobian(e, u) > 0.0)) return e;
  }
  return -1;
}

namespace {

// The largest principal Green-Lagrange strain of an element, in magnitude.
template <int D>
double PrincipalStrain(const Element<D>& element, const Vector& u) {
  const MatD<D> h = DisplacementGradient(element, u);
  const MatD<D> strain = 0.5 * (h + h.transpose() + h.transpose() * h);
  const Eigen::SelfAdjointEigenSolver<MatD<D>> eigen(strain, Eigen::EigenvaluesOnly);
  return eigen.eigenvalues().cwiseAbs().maxCoeff();
}

template <int D>
std::vector<double> StrainsOf(const std::vector<Element<D>>& elements, const Vector& u) {
  std::vector<double> strains;
  strains.reserve(elements.size());
  for (const Element<D>& element : elements) strains.push_back(PrincipalStrain(element, u));
  return strains;
}

}  // namespace

std::vector<double> FemModel::ElementStrains(const Vector& u) const {
  return dimension_ == 2 ? StrainsOf(elements2_, u) : StrainsOf(elements3_, u);
}

std::vector<double> FemModel::ElementVolumes() const {
  std::vector<double> volumes;
  for (const auto& el : elements2_) volumes.push_back(el.volume);
  for (const auto& el : elements3_) volumes.push_back(el.volume);
  return volumes;
}

double FemModel::Volume() const {
  double v = 0.0;
  for (const auto& el : elements2_) v += el.volume;
  for (const auto& el : elements3_) v += el.volume;
  return v;
}

double SimplexQuality(int dimension, const Matrix& corners) {
  // q = V / V_equilateral(rms edge): V_eq(l) = sqrt(3)/4 l^2 in 2D, l^3 / (6 sqrt(2)) in 3D.
  const int count = dimension + 1;
  double sum2 = 0.0;
  int edges = 0;
  for (int a = 0; a < count; ++a) {
    for (int b = a + 1; b < count; ++b) {
      sum2 += (corners.col(a) - corners.col(b)).squaredNorm();
      ++edges;
    }
  }
  const double rms = std::sqrt(sum2 / edges);
  if (!(rms > 0.0)) return 0.0;
  Matrix dm(dimension, dimension);
  for (int a = 0; a < dimension; ++a) dm.col(a) = corners.col(a + 1) - corners.col(0);
  if (dimension == 2) return (dm.determinant() / 2.0) / (std::sqrt(3.0) / 4.0 * rms * rms);
  return (dm.determinant() / 6.0) / (rms * rms * rms / (6.0 * std::sqrt(2.0)));
}

std::pair<double, int> FemModel::WorstQuality() const {
  double worst = std::numeric_limits<double>::infinity();
  int at = -1;
  const int d = dimension_;
  for (int e = 0; e < element_count(); ++e) {
    Matrix corners(d, d + 1);
    for (int a = 0; a <= d; ++a) {
      const int node = d == 2 ? elements2_[e].nodes[a] : elements3_[e].nodes[a];
      corners.col(a) = rest_.segment(d * node, d);
    }
    const double q = std::abs(SimplexQuality(d, corners));
    if (q < worst) {
      worst = q;
      at = e;
    }
  }
  return {worst, at};
}

}  // namespace springfit::fem
