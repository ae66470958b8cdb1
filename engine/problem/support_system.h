// A linear system restricted to one support: the degrees of freedom of the nodes a support
// leaves free, and the factorisation of a rest stiffness there.
//
// With f the external forces and u_c the prescribed displacements of the constrained nodes, the
// free displacements solve K_ff u_f = f_f - K_fc u_c. The factorisation is Eigen's simplicial
// Cholesky (AMD ordering) for 2D systems and small 3D ones, CHOLMOD's supernodal one
// (supernodal_cholesky.h) for 3D ones from kSupernodalMinDofs3d free degrees of freedom. With the
// reference BLAS both took the same time on fem-block-3d (3,000 free degrees of freedom); the
// threshold is set where a 3D factor's dense blocks grow, not measured (bench/RESULTS.md,
// "Large 3D meshes").
//
// Not thread-safe: one thread at a time per object (the gathers alone are safe to share).
#pragma once

#include <memory>
#include <vector>

#include <Eigen/Cholesky>
#include <Eigen/SparseCholesky>

#include "engine/linalg/supernodal_cholesky.h"
#include "engine/problem/rest_stiffness.h"

namespace springfit::response {

class SupportSystem {
 public:
  static constexpr int kSupernodalMinDofs3d = 6000;
  // `constrained[node]`: held (fixed or displaced) by this support.
  SupportSystem(int dimension, const std::vector<bool>& constrained);
  // A support that holds single degrees of freedom (`held_dofs[d * node + c]`), such as the
  // minimal one that removes the rigid motions alone (free_body.h). constrained() is then true
  // for a node with any held degree of freedom.
  static SupportSystem OfDofs(int dimension, const std::vector<bool>& held_dofs);
  // A support that holds what `base` holds and more nodes besides (a tool's nodes on the
  // support it pushes on). When `base` holds the matrix later given to Factorize() (its own
  // last Factorize() had the same matrix and succeeded), this system solves through base's
  // factor instead of factorising anew: the m degrees of freedom it holds besides border
  // base's system (a Schur complement: m solves with base's factor once, then per load one
  // solve with it and one with an m x m matrix; docs/ARCHITECTURE.md, "Tool pushes"). Else
  // it factorises as any system. `base` must outlive this system and must not be factorised
  // again while this one is used; base's SolveColumns() is then called from this one's
  // thread, which is safe beside base's own solves.
  SupportSystem(int dimension, const std::vector<bool>& constrained, const SupportSystem* base);
  SupportSystem(SupportSystem&&) = default;
  SupportSystem& operator=(SupportSystem&&) = default;

  int dimension() const { return dimension_; }
  int free_dofs() const { return static_cast<int>(free_dofs_.size()); }
  const std::vector<bool>& constrained() const { return constrained_; }
  // Per free degree of freedom, its index in the flat d*n vector.
  const std::vector<int>& free_dof_list() const { return free_dofs_; }
  // Per flat degree of freedom, its free index, or -1 when constrained.
  const std::vector<int>& free_index() const { return free_index_; }

  // Factorises `full` (d*n square) restricted to the free degrees of freedom, and keeps it for
  // the prescribed displacements' coupling. False when that restriction is not positive
  // definite: the support leaves a mechanism (or the matrix is indefinite).
  bool Factorize(const SparseMatrix& full);
  // Whether the last Factorize() solved through the base's factor (above).
  bool bordered() const { return bordered_; }
  // The free entries of a flat d*n vector.
  Vector Gather(const Vector& full) const;
  // A flat d*n vector: `free` on the free degrees of freedom, `prescribed`'s entries elsewhere.
  // Below, an empty `prescribed` means none (zero).
  Vector Scatter(const Vector& free, const Vector& prescribed) const;
  // The right-hand side f_f - K_fc u_c of a load (flat force and prescribed displacements).
  Vector RightHandSide(const Vector& force, const Vector& prescribed) const;
  // Overwrites b (free) with K_ff^-1 b. Precondition: Factorize() returned true.
  void Solve(Vector& b) const;
  // The same for every column of B (free x columns) at once.
  void SolveColumns(Matrix& b) const;
  // The full displacement (flat d*n) under a load.
  Vector Displacement(const Vector& force, const Vector& prescribed) const;
  // K_ff x for x on the free degrees of freedom (the matrix last given to Factorize()).
  Vector Multiply(const Vector& x) const;

 private:
  bool FactorizeOwn(const SparseMatrix& full);
  bool FactorizeBordered();
  // Overwrites b (free x columns) with K_ff^-1 b through the base's factor.
  void SolveBordered(Matrix& b) const;
  const SparseMatrix& Full() const { return bordered_ ? base_->full_ : full_; }

  int dimension_ = 2;
  std::vector<bool> constrained_;
  std::vector<int> free_dofs_;
  std::vector<int> free_index_;
  SparseMatrix full_;
  SparseMatrix restricted_;  // K_ff, lower triangle
  using Llt = Eigen::SimplicialLLT<SparseMatrix, Eigen::Lower, Eigen::AMDOrdering<int>>;
  std::unique_ptr<Llt> llt_;
  std::unique_ptr<SupernodalCholesky> supernodal_;  // (3D, from kSupernodalMinDofs3d)
  bool held_ = false;                               // the last Factorize()'s answer
  // The bordered solve: the base, per free degree of freedom its index among the base's free
  // ones, the base's free indices of the degrees of freedom held besides (E's columns), base's
  // K_ff^-1 E, and the Cholesky factor of the Schur complement E^T K_ff^-1 E.
  const SupportSystem* base_ = nullptr;
  bool bordered_ = false;
  std::vector<int> base_index_;
  std::vector<int> border_;
  Matrix border_solves_;
  Eigen::LLT<Matrix> schur_;
};

}  // namespace springfit::response
