// A model judged on probes (probe_bank.h): its displacement error under each, and the extreme
// generalised eigenvalues of its rest stiffness against the reference's on a support.
//
// E_p = |u_model - u_ref| / |u_ref| over the support's free nodes (the relative RMS nodal error
// of one load), both responses linear at rest; infinity where the model is not held by the
// support (a mechanism).
//
// The pencil (K_model, K_ref) on a support's free degrees of freedom: if every generalised
// eigenvalue lies in [lambda_min, lambda_max], then for every load on that support
//   |u_model - u_ref|_K_ref <= max(1/lambda_min - 1, 1 - 1/lambda_max) |u_ref|_K_ref,
// the energy norm's worst case (docs/ARCHITECTURE.md, "The certificate"). lambda_min near 0 is a
// mode the model leaves soft.
#pragma once

#include <cstdint>
#include <functional>
#include <limits>
#include <vector>

#include "engine/api/probe_fit_report.h"
#include "engine/probe_fit/probe_bank.h"
#include "engine/problem/support_system.h"
#include "engine/runtime/interruption.h"

namespace springfit::response {

// The model already factorised on a support by the caller (LinearizedResponse holds one per
// fitted support), or null: the judgements below then factorise it themselves. Either way the
// same matrix on the same support, so the same bits.
using FactorizedOn = std::function<const SupportSystem*(std::size_t support)>;

// How ProbeErrorsFor solves a tool load's support (support_system.h): through its base
// support's factor, bordered by the tool's nodes (the certificate's held-out pushes and grasps:
// in 3D each one's own factorisation costs as much as its base's), or with a factorisation of
// its own (the fit's judgements: they choose among nearly tied iterates, a choice that tips on
// the last bits, and the two solves agree to 1e-10, not bit for bit; a fitted tool support is
// factorised in the fit's linearisation anyway).
enum class ToolSolves { kOwnFactor, kThroughBase };

// Per probe of the bank, E_p where `include[p]` (NaN for the others). `interruption`, when set,
// is checked before each support's factorisation and every 16 probes' solves; it throws
// Interrupted when a stop is requested.
std::vector<double> ProbeErrorsFor(const ProbeBank& bank, const SparseMatrix& model,
                                   const std::vector<bool>& include,
                                   Interruption* interruption = nullptr,
                                   const FactorizedOn& factorized = {},
                                   ToolSolves tool_solves = ToolSolves::kOwnFactor);

// Of the finite and infinite entries of `errors` (NaN entries are skipped).
ErrorSummary Summarize(const std::vector<double>& errors);

std::vector<FamilyErrors> SummarizeByFamily(const ProbeBank& bank,
                                            const std::vector<double>& errors);
// sqrt of the mean over families of each family's mean E_p^2: every family counts alike.
double FamilyBalancedRms(const ProbeBank& bank, const std::vector<double>& errors);

// Lanczos steps of the pencil's extreme eigenvalues (full reorthogonalisation): enough for the
// extremes of every example to settle to three digits (bench/RESULTS.md, "Held modes").
inline constexpr int kLanczosIterations = 80;
// The seeds of the Lanczos start vectors: one for the pencil's largest eigenvalue, another for
// its smallest (the inverted pencil's largest), so that the two runs start apart. Fixed: the
// same model gets the same eigenvalues, bit for bit, on every run.
inline constexpr std::uint64_t kLargestEigenvalueSeed = 1;
inline constexpr std::uint64_t kSmallestEigenvalueSeed = 2;

// The smallest generalised eigenvalue of (model, reference) on `reference`'s support, whose
// factorisation it uses: 0 when the model is not held there.
// `interruption`, when set, is checked at every Lanczos iteration (one solve).
double SmallestGeneralizedEigenvalue(const SparseMatrix& model, const SupportSystem& reference,
                                     int iterations = kLanczosIterations,
                                     Interruption* interruption = nullptr);
// The same with the model factorised on that support by the caller.
double SmallestGeneralizedEigenvalue(const SupportSystem& model, const SupportSystem& reference,
                                     int iterations = kLanczosIterations,
                                     Interruption* interruption = nullptr);
// The displacements the model resists least against the reference on `reference`'s support:
// generalised eigenvectors of (model, reference), as Lanczos' Ritz vectors, smallest eigenvalue
// first, at most `count`, those with eigenvalue below `below`. Under the load K_ref v the
// reference moves by v and the model by v / lambda. None when the model is not held there.
struct SoftMode {
  double lambda = 0.0;
  Vector shape;  // flat d*n, 0 on the support's nodes
};
std::vector<SoftMode> SoftModes(const SparseMatrix& model, const SupportSystem& reference,
                                double below, int count, int iterations = kLanczosIterations,
                                Interruption* interruption = nullptr);
// The smallest generalised eigenvalue (as SmallestGeneralizedEigenvalue gives it, from the same
// Lanczos run) and the soft modes below `below` (as SoftModes), the model factorised on that
// support by the caller: one run for both.
struct LowestModes {
  double lambda_min = 0.0;
  std::vector<SoftMode> modes;
};
LowestModes SmallestGeneralizedEigenpairs(const SupportSystem& model,
                                          const SupportSystem& reference, double below, int count,
                                          int iterations = kLanczosIterations,
                                          Interruption* interruption = nullptr);
// The extremes on the support `m` and `r` share (the model's system and the reference's, not yet
// factorised), by Lanczos as below.
PencilExtremes PencilExtremesOn(const SparseMatrix& model, const SparseMatrix& reference,
                                SupportSystem m, SupportSystem r,
                                int iterations = kLanczosIterations,
                                Interruption* interruption = nullptr);
// By Lanczos iterations (full reorthogonalisation, at most `iterations`, seeded) in the
// reference's energy inner product, on the free degrees of freedom of `constrained`.
// `interruption`, when set, is checked after each factorisation and at every Lanczos iteration.
PencilExtremes GeneralizedEigenvalueExtremes(const SparseMatrix& model,
                                             const SparseMatrix& reference,
                                             const std::vector<bool>& constrained, int dimension,
                                             int iterations = kLanczosIterations,
                                             Interruption* interruption = nullptr);

}  // namespace springfit::response
