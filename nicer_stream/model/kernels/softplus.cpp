// softplus(beta z) / beta and sigmoid(beta z) in one pass over z, for the CPU: the geometry
// MLPs' activation and its derivative. The reference (model/softplus.py) takes ~10 tensor passes
// (mul, abs, clamp, neg, exp, add, log, relu, add, div, and sigmoid's own). Same formula:
// a = beta z, e = exp(-min(|a|, 80)), softplus = (max(a, 0) + log(1 + e)) / beta,
// sigmoid = 1 / (1 + e) for a >= 0, else e / (1 + e). Built with -ffast-math so that exp and log
// vectorise (glibc's libmvec); NaN inputs are caught on their bits and passed through.
#include <torch/extension.h>
#include <algorithm>
#include <cmath>
#include <cstdint>
#include <cstring>
#include <vector>

// NaN test on the bits: -ffast-math (needed for the vector exp/log) folds x != x away.
static inline bool is_nan(float x) { uint32_t b; std::memcpy(&b, &x, 4); return (b & 0x7fffffffu) > 0x7f800000u; }
static inline bool is_nan(double x) { uint64_t b; std::memcpy(&b, &x, 8); return (b & 0x7fffffffffffffffull) > 0x7ff0000000000000ull; }

// Every element goes through the same 16-wide vector code (whole blocks in place, the tail
// padded in a local block): a scalar epilogue or an alignment peel would give some elements
// libm's scalar exp/log instead, whose last bit differs, so a value would depend on its position.
constexpr int64_t kBlock = 16;

template <typename T>
static inline void block(const T* __restrict zb, T* __restrict spb, T* __restrict sgb, T beta, T inv) {
#pragma omp simd
  for (int64_t i = 0; i < kBlock; ++i) {
    T a = beta * zb[i];
    const bool nan = is_nan(zb[i]);
    T m = std::fabs(a);
    m = m < T(80) ? m : T(80);
    T e = std::exp(-m);
    T r = a > T(0) ? a : T(0);
    T v = (r + std::log(T(1) + e)) * inv;
    spb[i] = nan ? zb[i] : v;
    T d = T(1) / (T(1) + e);
    T w = a >= T(0) ? d : e * d;
    sgb[i] = nan ? zb[i] : w;
  }
}

template <typename T>
static void run(const T* z, T* sp, T* sg, int64_t n, T beta) {
  const T inv = T(1) / beta;
#pragma omp parallel for schedule(static)
  for (int64_t c = 0; c < n; c += 4096) {
    const int64_t end = std::min(n, c + 4096);
    alignas(64) T zb[kBlock], spb[kBlock], sgb[kBlock];
    int64_t b = c;
    for (; b + kBlock <= end; b += kBlock) {  // whole blocks straight from and to the tensors
      block(z + b, sp + b, sg ? sg + b : sgb, beta, inv);
    }
    if (b < end) {  // the tail, padded, through the same code
      const int64_t k = end - b;
      for (int64_t i = 0; i < kBlock; ++i) zb[i] = i < k ? z[b + i] : T(0);
      block(zb, spb, sgb, beta, inv);
      std::memcpy(sp + b, spb, k * sizeof(T));
      if (sg) std::memcpy(sg + b, sgb, k * sizeof(T));
    }
  }
}

std::vector<torch::Tensor> softplus_sigmoid(torch::Tensor z, double beta, bool with_sigmoid) {
  z = z.contiguous();
  auto sp = torch::empty_like(z);
  auto sg = with_sigmoid ? torch::empty_like(z) : torch::empty({0}, z.options());
  AT_DISPATCH_FLOATING_TYPES(z.scalar_type(), "softplus_sigmoid", [&] {
    run<scalar_t>(z.data_ptr<scalar_t>(), sp.data_ptr<scalar_t>(), with_sigmoid ? sg.data_ptr<scalar_t>() : nullptr,
                  z.numel(), (scalar_t)beta);
  });
  return {sp, sg};
}

// One layer of the SDF-gradient sweep's adjoint (model/sdf_grad_mlp.py), in one pass:
// ubar = vbar s and zbar = vbar u beta s (1 - s), all (N, H) contiguous. The tensor form takes
// six passes and four temporaries.
template <typename T>
static void adjoint(const T* V, const T* U, const T* S, T* UB, T* ZB, int64_t n, T beta) {
#pragma omp parallel for schedule(static)
  for (int64_t c = 0; c < n; c += 4096) {
    const int64_t end = std::min(n, c + 4096);
#pragma omp simd
    for (int64_t i = c; i < end; ++i) {
      const T v = V[i], si = S[i];
      UB[i] = v * si;
      ZB[i] = v * U[i] * (beta * si * (T(1) - si));
    }
  }
}

std::vector<torch::Tensor> sweep_adjoint(torch::Tensor vbar, torch::Tensor u, torch::Tensor s, double beta) {
  vbar = vbar.contiguous(); u = u.contiguous(); s = s.contiguous();
  auto ubar = torch::empty_like(vbar), zbar = torch::empty_like(vbar);
  AT_DISPATCH_FLOATING_TYPES(vbar.scalar_type(), "sweep_adjoint", [&] {
    adjoint<scalar_t>(vbar.data_ptr<scalar_t>(), u.data_ptr<scalar_t>(), s.data_ptr<scalar_t>(),
                      ubar.data_ptr<scalar_t>(), zbar.data_ptr<scalar_t>(), vbar.numel(), (scalar_t)beta);
  });
  return {ubar, zbar};
}

PYBIND11_MODULE(TORCH_EXTENSION_NAME, m) {
  m.def("softplus_sigmoid", &softplus_sigmoid, "softplus(beta z)/beta and sigmoid(beta z)");
  m.def("sweep_adjoint", &sweep_adjoint, "ubar = vbar s, zbar = vbar u beta s (1 - s)");
}
