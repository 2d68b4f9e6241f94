// One Kalman predict + update, Joseph form, Cholesky-solved gain: the same
// step as aidnav's `KalmanFilter::{predict, update}`, in fixed-size Eigen.
// Build and run with bench/run_comparison.sh (g++ -O3 -march=native).
// With -DCHECKS it also performs the finiteness / symmetry checks aidnav does.
#include <Eigen/Dense>
#include <algorithm>
#include <chrono>
#include <cstdio>
#include <vector>

template <int N, int M>
struct Problem {
  Eigen::Matrix<double, N, N> phi, q, p;
  Eigen::Matrix<double, M, N> h;
  Eigen::Matrix<double, M, M> r;
  Eigen::Matrix<double, N, 1> x;
  Eigen::Matrix<double, M, 1> z;
  Problem() {
    for (int i = 0; i < N; ++i)
      for (int j = 0; j < N; ++j) {
        phi(i, j) = i == j ? 1.0 : 0.01 * (double((i * 7 + j * 3) % 11) - 5.0) / 5.0;
        q(i, j) = i == j ? 1e-4 * (1.0 + i) : 0.0;
      }
    for (int i = 0; i < M; ++i)
      for (int j = 0; j < N; ++j) h(i, j) = i == j ? 1.0 : (j == i + M ? 0.1 : 0.0);
    for (int i = 0; i < M; ++i)
      for (int j = 0; j < M; ++j) r(i, j) = i == j ? 0.5 + 0.1 * i : 0.01;
    Eigen::Matrix<double, N, N> a;
    for (int i = 0; i < N; ++i)
      for (int j = 0; j < N; ++j) a(i, j) = (double((i * 5 + j * 13) % 17) - 8.0) / 8.0;
    p = a * a.transpose() / double(N) + Eigen::Matrix<double, N, N>::Identity();
    x.setZero();
    for (int i = 0; i < M; ++i) z(i) = 0.1 * i;
  }
};

template <int N, int M>
__attribute__((noinline)) bool step(Problem<N, M>& s) {
#ifdef CHECKS
  if (!s.phi.allFinite() || !s.q.allFinite() || !s.h.allFinite() || !s.r.allFinite() || !s.z.allFinite()) return false;
  if (!s.q.isApprox(s.q.transpose()) || !s.r.isApprox(s.r.transpose())) return false;
#endif
  s.x = s.phi * s.x;
  Eigen::Matrix<double, N, N> p = s.phi * s.p * s.phi.transpose() + s.q;
  s.p = 0.5 * (p + p.transpose());
  Eigen::Matrix<double, M, 1> y = s.z - s.h * s.x;
  Eigen::Matrix<double, M, N> hp = s.h * s.p;
  Eigen::Matrix<double, M, M> hph = hp * s.h.transpose();
  Eigen::Matrix<double, M, M> S = 0.5 * (hph + hph.transpose()) + s.r;
  Eigen::LLT<Eigen::Matrix<double, M, M>> llt(S);
  if (llt.info() != Eigen::Success) return false;
  double nis = y.dot(llt.solve(y));
  Eigen::Matrix<double, N, M> k = llt.solve(hp).transpose();
  s.x += k * y;
#ifdef NAIVE_JOSEPH
  Eigen::Matrix<double, N, N> ikh = Eigen::Matrix<double, N, N>::Identity() - k * s.h;
  p = ikh * s.p * ikh.transpose() + k * s.r * k.transpose();
#else
  // Joseph form in the rank-m association, as aidnav does:
  // A = P - K (HP) = (I-KH)P;  A (I-KH)^T + K R K^T = A + (K R - A H^T) K^T.
  Eigen::Matrix<double, N, N> a = s.p;
  a.noalias() -= k * hp;
  Eigen::Matrix<double, N, M> d = k * s.r;
  d.noalias() -= a * s.h.transpose();
  p = a;
  p.noalias() += d * k.transpose();
#endif
  s.p = 0.5 * (p + p.transpose());
#ifdef CHECKS
  if (!s.p.allFinite() || !s.x.allFinite() || !k.allFinite()) return false;
#endif
  return nis >= 0.0;
}

template <int N, int M>
void run(const char* name) {
  Problem<N, M> s;
  const int iters = 200000;
  std::vector<double> ns;
  for (int rep = 0; rep < 7; ++rep) {
    auto t0 = std::chrono::steady_clock::now();
    int ok = 0;
    for (int i = 0; i < iters; ++i) ok += step<N, M>(s);
    auto t1 = std::chrono::steady_clock::now();
    if (ok != iters) std::printf("step failed\n");
    ns.push_back(std::chrono::duration<double, std::nano>(t1 - t0).count() / iters);
  }
  std::sort(ns.begin(), ns.end());
  std::printf("%s: median %.1f ns per predict+update (min %.1f, max %.1f; P00=%g)\n", name, ns[3], ns[0], ns[6], s.p(0, 0));
}

int main() {
  run<15, 6>("eigen fixed 15x6");
  run<21, 6>("eigen fixed 21x6");
}
