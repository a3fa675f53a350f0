// The large-steps parameterization (Nicolet et al. 2021): vertices x are
// optimized as u = (I + λL) x with a cached sparse Cholesky factor (Eigen).
#pragma once

#include <algorithm>
#include <cstddef>
#include <cstdint>
#include <stdexcept>
#include <utility>
#include <vector>

#include <Eigen/Sparse>
#include <Eigen/SparseCholesky>

#include "difftrans/optim/adam.hpp"

namespace difftrans::optim {

using SparseMatrixd = Eigen::SparseMatrix<double>;

// The undirected edges (a < b) of a triangle mesh, sorted and unique.
inline std::vector<std::pair<std::int32_t, std::int32_t>> mesh_edges(const std::int32_t* triangles,
                                                                     std::int32_t num_triangles) {
  std::vector<std::pair<std::int32_t, std::int32_t>> edges;
  edges.reserve(std::size_t(num_triangles) * 3);
  for (std::int32_t f = 0; f < num_triangles; ++f)
    for (int k = 0; k < 3; ++k) {
      const std::int32_t a = triangles[3 * f + k], b = triangles[3 * f + (k + 1) % 3];
      if (a != b) edges.emplace_back(std::min(a, b), std::max(a, b));
    }
  std::sort(edges.begin(), edges.end());
  edges.erase(std::unique(edges.begin(), edges.end()), edges.end());
  return edges;
}

// The uniform (combinatorial) Laplacian: L_ii = degree of i, L_ij = −1 for
// every edge (i, j).
inline SparseMatrixd uniform_laplacian(const std::int32_t* triangles, std::int32_t num_triangles,
                                       std::int32_t num_vertices) {
  const auto edges = mesh_edges(triangles, num_triangles);
  std::vector<Eigen::Triplet<double>> t;
  t.reserve(edges.size() * 4);
  for (const auto& [a, b] : edges) {
    if (a < 0 || b >= num_vertices) throw std::out_of_range("uniform_laplacian: vertex index out of range");
    t.emplace_back(a, b, -1.0);
    t.emplace_back(b, a, -1.0);
    t.emplace_back(a, a, 1.0);
    t.emplace_back(b, b, 1.0);
  }
  SparseMatrixd L(num_vertices, num_vertices);
  L.setFromTriplets(t.begin(), t.end());  // duplicates are summed
  return L;
}

// Σ over coordinates of xᵀ L x = Σ over edges |x_i − x_j|² for 3 values per
// vertex: how rough a displacement field on the mesh is.
inline double laplacian_energy(const SparseMatrixd& L, const float* values) {
  double e = 0.0;
  for (int k = 0; k < L.outerSize(); ++k)
    for (SparseMatrixd::InnerIterator it(L, k); it; ++it)
      for (int c = 0; c < 3; ++c)
        e += it.value() * double(values[3 * it.row() + c]) * double(values[3 * it.col() + c]);
  return e;
}

// M = I + λL for a mesh topology, with its sparse Cholesky factor kept until
// the topology (the triangle array, the vertex count) or λ changes. Vectors
// are 3 floats per vertex (x y z), solved as one n × 3 right-hand side.
class LargeSteps {
 public:
  explicit LargeSteps(double lambda = 19.0) : lambda_(lambda) {}

  // Makes M (and its factor) match this topology; returns true when it had
  // to factorize, false when the cached factor was reused.
  bool set_topology(const std::int32_t* triangles, std::int32_t num_triangles, std::int32_t num_vertices) {
    if (factored_ && num_vertices == num_vertices_ && lambda_ == factored_lambda_ &&
        std::size_t(num_triangles) * 3 == triangles_.size() &&
        std::equal(triangles_.begin(), triangles_.end(), triangles))
      return false;
    triangles_.assign(triangles, triangles + std::size_t(num_triangles) * 3);
    num_vertices_ = num_vertices;
    factorize();
    return true;
  }
  bool set_topology(const std::vector<std::int32_t>& triangles, std::int32_t num_vertices) {
    return set_topology(triangles.data(), std::int32_t(triangles.size() / 3), num_vertices);
  }

  // A new λ takes effect at the next set_topology (which then refactorizes)
  // or refactor_lambda.
  void set_lambda(double lambda) { lambda_ = lambda; }
  double lambda() const { return lambda_; }
  // Refactorizes M on the current topology when λ changed since the factor;
  // returns whether it had to.
  bool refactor_lambda() {
    require();
    if (lambda_ == factored_lambda_) return false;
    factorize();
    return true;
  }

  std::int32_t num_vertices() const { return num_vertices_; }
  // How many times M has been factorized: unchanged while the topology is.
  int factorizations() const { return factorizations_; }
  const SparseMatrixd& matrix() const { return M_; }
  const SparseMatrixd& laplacian() const { return L_; }

  // u = M x.
  void to_u(const float* x, float* u) const {
    require();
    const Eigen::MatrixX3d r = M_ * load(x);
    store(r, u);
  }
  std::vector<float> to_u(const std::vector<float>& x) const {
    check(x.size());
    std::vector<float> u(x.size());
    to_u(x.data(), u.data());
    return u;
  }

  // x = M⁻¹ u (the cached factor).
  void from_u(const float* u, float* x) const {
    require();
    const Eigen::MatrixX3d r = solver_.solve(load(u));
    store(r, x);
  }
  std::vector<float> from_u(const std::vector<float>& u) const {
    check(u.size());
    std::vector<float> x(u.size());
    from_u(u.data(), x.data());
    return x;
  }

  // Backward of x = M⁻¹ u: dL/du = M⁻ᵀ dL/dx = M⁻¹ dL/dx (M is symmetric).
  void backward(const float* grad_x, float* grad_u) const { from_u(grad_x, grad_u); }
  std::vector<float> backward(const std::vector<float>& grad_x) const { return from_u(grad_x); }

 private:
  void factorize() {
    L_ = uniform_laplacian(triangles_.data(), std::int32_t(triangles_.size() / 3), num_vertices_);
    SparseMatrixd I(num_vertices_, num_vertices_);
    I.setIdentity();
    M_ = I + lambda_ * L_;
    M_.makeCompressed();
    solver_.compute(M_);
    if (solver_.info() != Eigen::Success) throw std::runtime_error("LargeSteps: Cholesky factorization failed");
    factored_ = true;
    factored_lambda_ = lambda_;
    ++factorizations_;
  }

  void require() const {
    if (!factored_) throw std::logic_error("LargeSteps: set_topology first");
  }
  void check(std::size_t n) const {
    require();
    if (n != std::size_t(num_vertices_) * 3) throw std::invalid_argument("LargeSteps: expected 3 values per vertex");
  }

  Eigen::MatrixX3d load(const float* v) const {
    Eigen::MatrixX3d m(num_vertices_, 3);
    for (std::int32_t i = 0; i < num_vertices_; ++i)
      for (int c = 0; c < 3; ++c) m(i, c) = double(v[3 * i + c]);
    return m;
  }
  void store(const Eigen::MatrixX3d& m, float* v) const {
    for (std::int32_t i = 0; i < num_vertices_; ++i)
      for (int c = 0; c < 3; ++c) v[3 * i + c] = float(m(i, c));
  }

  double lambda_;
  double factored_lambda_ = 0.0;
  bool factored_ = false;
  int factorizations_ = 0;
  std::int32_t num_vertices_ = 0;
  std::vector<std::int32_t> triangles_;
  SparseMatrixd L_, M_;
  Eigen::SimplicialLLT<SparseMatrixd> solver_;
};

// Vertex refinement the large-steps way: holds u = M x and AdamUniform on u.
// Each step takes dL/dx, maps it to dL/du = M⁻¹ dL/dx, steps u and writes
// x = M⁻¹ u. Call reset() after the topology changes (e.g. remeshing).
class LargeStepsOptimizer {
 public:
  explicit LargeStepsOptimizer(double lambda = 19.0, AdamOptions options = {}) : steps_(lambda), adam_(0, options) {}

  // Starts from positions x (3 per vertex) on this topology.
  void reset(const std::vector<float>& x, const std::vector<std::int32_t>& triangles) {
    steps_.set_topology(triangles, std::int32_t(x.size() / 3));
    u_ = steps_.to_u(x);
    adam_.reset(u_.size());
  }

  // One step at learning rate lr; x is overwritten with the new positions.
  void step(std::vector<float>& x, const std::vector<float>& grad_x, float lr) {
    if (x.size() != u_.size() || grad_x.size() != u_.size())
      throw std::invalid_argument("LargeStepsOptimizer::step: size mismatch (reset after remeshing)");
    const std::vector<float> grad_u = steps_.backward(grad_x);
    adam_.step(u_, grad_u, lr);
    steps_.from_u(u_.data(), x.data());
  }
  void step(std::vector<float>& x, const std::vector<float>& grad_x) { step(x, grad_x, adam_.options().lr); }

  // λ for the next reset() or restore().
  void set_lambda(double lambda) { steps_.set_lambda(lambda); }
  double lambda() const { return steps_.lambda(); }

  // A new λ in the middle of a fit (coarse to fine: a large λ moves the
  // whole surface, a small one its detail), keeping the positions x: M is
  // refactorized, u = M x, and Adam's moments restart (they were moments of
  // the old u). Returns false, changing nothing, when λ is already this one.
  bool change_lambda(double lambda, const std::vector<float>& x) {
    if (lambda == steps_.lambda()) return false;
    if (x.size() != u_.size()) throw std::invalid_argument("LargeStepsOptimizer::change_lambda: size mismatch");
    steps_.set_lambda(lambda);
    steps_.refactor_lambda();
    u_ = steps_.to_u(x);
    adam_.reset(u_.size());
    return true;
  }

  const LargeSteps& parameterization() const { return steps_; }
  const AdamUniform& adam() const { return adam_; }
  const std::vector<float>& u() const { return u_; }

  // Continues from a saved u() and adam().state() on this topology (the
  // positions follow from u; a checkpoint need not store them).
  void restore(const std::vector<std::int32_t>& triangles, std::int32_t vertices, const std::vector<float>& u,
               const AdamState& adam) {
    if (u.size() != 3 * std::size_t(vertices) || adam.g1.size() != u.size())
      throw std::invalid_argument("LargeStepsOptimizer::restore: sizes do not match the vertex count");
    steps_.set_topology(triangles, vertices);
    u_ = u;
    adam_.restore(adam);
  }

 private:
  LargeSteps steps_;
  AdamUniform adam_;
  std::vector<float> u_;
};

}  // namespace difftrans::optim
