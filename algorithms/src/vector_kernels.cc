#include "vector_kernels.h"

namespace ambdiag::detail {

namespace {

typedef double Vec4 __attribute__((vector_size(32)));

}  // namespace

AMBDIAG_VECTOR_CLONES void gram(const double* v, Eigen::Index n, Eigen::Index k, const double* w, Eigen::Index p,
                                double* c) {
  const Eigen::Index n4 = n / 4 * 4;
  // V streamed once (j outer): for a large system W stays in cache, V not.
  for (Eigen::Index j = 0; j < k; ++j) {
    const double* vj = v + j * n;
    for (Eigen::Index q = 0; q < p; ++q) {
      const double* wq = w + q * n;
      Vec4 acc = {0, 0, 0, 0};
      for (Eigen::Index i = 0; i < n4; i += 4) {
        Vec4 a, b;  // unaligned loads
        __builtin_memcpy(&a, vj + i, sizeof a);
        __builtin_memcpy(&b, wq + i, sizeof b);
        acc += a * b;
      }
      double s = (acc[0] + acc[1]) + (acc[2] + acc[3]);
      for (Eigen::Index i = n4; i < n; ++i) s += vj[i] * wq[i];
      c[q * k + j] = s;
    }
  }
}

AMBDIAG_VECTOR_CLONES void subtract_product(const double* v, Eigen::Index n, Eigen::Index k, const double* c,
                                            Eigen::Index p, double* w) {
  const Eigen::Index n4 = n / 4 * 4;
  for (Eigen::Index j = 0; j < k; ++j) {
    const double* vj = v + j * n;
    for (Eigen::Index q = 0; q < p; ++q) {
      double* wq = w + q * n;
      const double f = c[q * k + j];
      for (Eigen::Index i = 0; i < n4; i += 4) {
        Vec4 a, b;
        __builtin_memcpy(&a, vj + i, sizeof a);
        __builtin_memcpy(&b, wq + i, sizeof b);
        b -= f * a;
        __builtin_memcpy(wq + i, &b, sizeof b);
      }
      for (Eigen::Index i = n4; i < n; ++i) wq[i] -= f * vj[i];
    }
  }
}

}  // namespace ambdiag::detail
