// The geometry input's compiled passes (model/positional.py, model/sdf_grad_assembly.py: the
// formulas and the tensor-op references), for the CPU.
//
// gamma(x) = [x (3), sin(f_l x_k) at 3 + 3l + k, cos(f_l x_k) at 3 + 3L + 3l + k], f_l = 2^l pi
// (P = 3 + 6L columns), in one pass; every value goes through the same 16-wide vector sin/cos (the
// tail padded, as in softplus.cpp), so a point's encoding does not depend on where it sits in the
// batch. Its adjoint for a = d./d gamma (the encoding's Jacobian applied to a):
//   (J^T a)_k = a_k + sum_l f_l (cos_lk a_sin,lk - sin_lk a_cos,lk), read from the encoding itself.
//
// The SDF's spatial gradient assembled from its parts i = (u_i (N, P + F_i), J_i (N, 3, F_i)):
//   grad = J_gamma^T (sum_i u_i[:, :P]) + sum_i J_i u_i[:, P:]
// and its adjoint, one pass each (the tensor form: ~25 autograd nodes, four (N, 3, F) temporaries).
//
// Built with -ffast-math so that sin and cos vectorise (glibc's libmvec); the sums' last bits
// depend on the CPU's vector width (tests use tolerances).
#include <torch/extension.h>
#include <algorithm>
#include <cmath>
#include <vector>

constexpr int64_t kBlock = 16;    // coordinates per vector block
constexpr int64_t kChunk = 3072;  // coordinates per parallel chunk of the encoding
constexpr int64_t kRows = 256;    // rows per parallel chunk of the assembly

// For one point, per (l, k): out_sin = sign g_k f_l src_cos, out_cos = -sign g_k f_l src_sin (the sin and cos
// columns of the adjoint's pairs; src the encoding or a vector in its layout, P columns).
template <typename T>
static inline void pair_columns(const T* src, const T* gk, T sign, const T* freqs, int64_t levels, T* out) {
  for (int64_t l = 0; l < levels; ++l)
    for (int k = 0; k < 3; ++k) {
      const int64_t is = 3 + 3 * l + k, ic = 3 + 3 * levels + 3 * l + k;
      out[is] = sign * gk[k] * freqs[l] * src[ic];
      out[ic] = -sign * gk[k] * freqs[l] * src[is];
    }
}

// (J_gamma^T a)_k for one point: e its encoding (P,), a (P,).
template <typename T>
static inline T encoding_adjoint(const T* e, const T* a, const T* freqs, int64_t levels, int k) {
  T s = a[k];
  for (int64_t l = 0; l < levels; ++l) {
    const int64_t is = 3 + 3 * l + k, ic = 3 + 3 * levels + 3 * l + k;
    s += freqs[l] * (e[ic] * a[is] - e[is] * a[ic]);
  }
  return s;
}

// sin and cos of f x over a contiguous block of kBlock coordinates (the vector code for every value).
template <typename T>
static inline void sincos_block(const T* __restrict xb, T f, T* __restrict sb, T* __restrict cb) {
  // Two loops: in one, the compiler fuses sin and cos into scalar `sincos` calls.
#pragma omp simd
  for (int64_t i = 0; i < kBlock; ++i) sb[i] = std::sin(xb[i] * f);
#pragma omp simd
  for (int64_t i = 0; i < kBlock; ++i) cb[i] = std::cos(xb[i] * f);
}

// x (N, 3) flattened: rows in chunks; within a chunk every level's sin and cos are computed over the
// chunk's contiguous coordinates (vector code, the tail padded), then each row's three values per
// level are copied to columns 3 + 3l and 3 + 3L + 3l.
template <typename T>
static void encode(const T* x, T* enc, int64_t n, const T* freqs, int64_t levels) {
  const int64_t P = 3 + 6 * levels;
  constexpr int64_t kRowsPer = kChunk / 3 / kBlock * kBlock;  // rows per chunk; 3 kRowsPer is a multiple of kBlock
#pragma omp parallel for schedule(static)
  for (int64_t c = 0; c < n; c += kRowsPer) {
    const int64_t rows = std::min(kRowsPer, n - c), m = 3 * rows;
    const int64_t padded = (m + kBlock - 1) / kBlock * kBlock;
    std::vector<T> xb(padded, T(0)), sb(padded), cb(padded);
    std::copy(x + 3 * c, x + 3 * c + m, xb.begin());
    for (int64_t r = 0; r < rows; ++r)
      for (int k = 0; k < 3; ++k) enc[(c + r) * P + k] = xb[3 * r + k];
    for (int64_t l = 0; l < levels; ++l) {
      for (int64_t b = 0; b < padded; b += kBlock) sincos_block(xb.data() + b, freqs[l], sb.data() + b, cb.data() + b);
      for (int64_t r = 0; r < rows; ++r) {
        T* e = enc + (c + r) * P;
        for (int k = 0; k < 3; ++k) {
          e[3 + 3 * l + k] = sb[3 * r + k];
          e[3 + 3 * levels + 3 * l + k] = cb[3 * r + k];
        }
      }
    }
  }
}

template <typename T>
static void encode_adjoint(const T* enc, const T* g, T* gx, int64_t n, const T* freqs, int64_t levels) {
  const int64_t P = 3 + 6 * levels;
#pragma omp parallel for schedule(static)
  for (int64_t r = 0; r < n; ++r)
    for (int k = 0; k < 3; ++k) gx[r * 3 + k] = encoding_adjoint(enc + r * P, g + r * P, freqs, levels, k);
}

// freqs (L,): f_l, from model/positional.py (the reference's own values), x's dtype.
torch::Tensor positional_encode(torch::Tensor x, torch::Tensor freqs) {
  x = x.contiguous(); freqs = freqs.contiguous();
  const int64_t levels = freqs.numel();
  const int64_t n = x.size(0);
  auto enc = torch::empty({n, 3 + 6 * levels}, x.options());
  AT_DISPATCH_FLOATING_TYPES(x.scalar_type(), "positional_encode", [&] {
    encode<scalar_t>(x.data_ptr<scalar_t>(), enc.data_ptr<scalar_t>(), n, freqs.data_ptr<scalar_t>(), levels);
  });
  return enc;
}

torch::Tensor positional_adjoint(torch::Tensor enc, torch::Tensor g, torch::Tensor freqs) {
  enc = enc.contiguous(); g = g.contiguous(); freqs = freqs.contiguous();
  const int64_t levels = freqs.numel();
  const int64_t n = enc.size(0);
  auto gx = torch::empty({n, 3}, enc.options());
  AT_DISPATCH_FLOATING_TYPES(enc.scalar_type(), "positional_adjoint", [&] {
    encode_adjoint<scalar_t>(enc.data_ptr<scalar_t>(), g.data_ptr<scalar_t>(), gx.data_ptr<scalar_t>(), n,
                             freqs.data_ptr<scalar_t>(), levels);
  });
  return gx;
}

// body(first, end) over chunks of kRows rows, on OpenMP's threads.
template <typename Body>
static void parallel_rows(int64_t n, const Body& body) {
#pragma omp parallel for schedule(static)
  for (int64_t c = 0; c < n; c += kRows) body(c, std::min(n, c + kRows));
}

// a = sum_i u_i[r, :P] (the parts' encoding columns of row r).
template <typename T>
static inline void encoding_columns(const std::vector<const T*>& u, const std::vector<int64_t>& Fs, int64_t r,
                                    int64_t P, T* a) {
  for (int64_t j = 0; j < P; ++j) a[j] = u[0][r * (P + Fs[0]) + j];
  for (size_t i = 1; i < u.size(); ++i)
    for (int64_t j = 0; j < P; ++j) a[j] += u[i][r * (P + Fs[i]) + j];
}

template <typename T>
static void forward_rows(const T* pe, const std::vector<const T*>& u, const std::vector<const T*>& jac,
                         T* grad, int64_t n, const T* freqs, int64_t levels, const std::vector<int64_t>& Fs) {
  const int64_t P = 3 + 6 * levels;
  parallel_rows(n, [&](int64_t c, int64_t end) {
    std::vector<T> a(P);
    for (int64_t r = c; r < end; ++r) {
      encoding_columns(u, Fs, r, P, a.data());
      const T* e = pe + r * P;
      for (int k = 0; k < 3; ++k) {
        T s = encoding_adjoint(e, a.data(), freqs, levels, k);
        for (size_t i = 0; i < u.size(); ++i) {
          const int64_t F = Fs[i];
          const T* J = jac[i] + (r * 3 + k) * F;
          const T* ug = u[i] + r * (P + F) + P;
          T t = 0;
#pragma omp simd reduction(+ : t)
          for (int64_t f = 0; f < F; ++f) t += J[f] * ug[f];
          s += t;
        }
        grad[r * 3 + k] = s;
      }
    }
  });
}

template <typename T>
static void backward_rows(const T* pe, const std::vector<const T*>& u, const std::vector<const T*>& jac,
                          const T* g, T* g_pe, const std::vector<T*>& g_u, const std::vector<T*>& g_jac,
                          int64_t n, const T* freqs, int64_t levels, const std::vector<int64_t>& Fs) {
  const int64_t P = 3 + 6 * levels;
  parallel_rows(n, [&](int64_t c, int64_t end) {
    std::vector<T> a(P), ga(P);
    for (int64_t r = c; r < end; ++r) {
      const T* e = pe + r * P;
      const T g0 = g[r * 3], g1 = g[r * 3 + 1], g2 = g[r * 3 + 2];
      const T gk[3] = {g0, g1, g2};
      // d grad / d a: the same for every part's encoding columns.
      for (int k = 0; k < 3; ++k) ga[k] = gk[k];
      pair_columns(e, gk, T(1), freqs, levels, ga.data());
      if (g_pe) {  // d grad / d gamma: through the sin and cos the adjoint reads
        encoding_columns(u, Fs, r, P, a.data());
        T* gp = g_pe + r * P;
        for (int k = 0; k < 3; ++k) gp[k] = 0;
        pair_columns(a.data(), gk, T(-1), freqs, levels, gp);
      }
      for (size_t i = 0; i < u.size(); ++i) {
        const int64_t F = Fs[i], W = P + F;
        const T* J = jac[i] + r * 3 * F;
        const T* ug = u[i] + r * W + P;
        if (g_u[i]) {
          T* __restrict gu = g_u[i] + r * W;
          for (int64_t j = 0; j < P; ++j) gu[j] = ga[j];
#pragma omp simd
          for (int64_t f = 0; f < F; ++f) gu[P + f] = g0 * J[f] + g1 * J[F + f] + g2 * J[2 * F + f];
        }
        if (g_jac[i]) {
          T* __restrict gj = g_jac[i] + r * 3 * F;
          for (int k = 0; k < 3; ++k)
#pragma omp simd
            for (int64_t f = 0; f < F; ++f) gj[k * F + f] = gk[k] * ug[f];
        }
      }
    }
  });
}

// pe (N, P); us: parts' u (N, P + F_i); jacs: parts' J (N, 3, F_i); freqs (L,) = f_l; all contiguous, one dtype.
torch::Tensor assemble_forward(torch::Tensor pe, std::vector<torch::Tensor> us, std::vector<torch::Tensor> jacs,
                               torch::Tensor freqs) {
  const int64_t n = pe.size(0), levels = freqs.numel();
  std::vector<int64_t> Fs;
  for (auto& t : jacs) Fs.push_back(t.size(2));
  auto grad = torch::empty({n, 3}, pe.options());
  AT_DISPATCH_FLOATING_TYPES(pe.scalar_type(), "assemble_forward", [&] {
    std::vector<const scalar_t*> u, j;
    for (auto& t : us) u.push_back(t.data_ptr<scalar_t>());
    for (auto& t : jacs) j.push_back(t.data_ptr<scalar_t>());
    forward_rows<scalar_t>(pe.data_ptr<scalar_t>(), u, j, grad.data_ptr<scalar_t>(), n, freqs.data_ptr<scalar_t>(),
                           levels, Fs);
  });
  return grad;
}

// Returns [g_pe (or empty), g_u_0, g_jac_0, g_u_1, g_jac_1, ...]; a part's gradient is empty
// where `need` (per part: u, jac) says it is not needed.
std::vector<torch::Tensor> assemble_backward(torch::Tensor pe, std::vector<torch::Tensor> us,
                                             std::vector<torch::Tensor> jacs, torch::Tensor g, torch::Tensor freqs,
                                             bool need_pe, std::vector<bool> need) {
  const int64_t n = pe.size(0), levels = freqs.numel();
  std::vector<int64_t> Fs;
  for (auto& t : jacs) Fs.push_back(t.size(2));
  auto empty = torch::empty({0}, pe.options());
  std::vector<torch::Tensor> out{need_pe ? torch::empty_like(pe) : empty};
  for (size_t i = 0; i < us.size(); ++i) {
    out.push_back(need[2 * i] ? torch::empty_like(us[i]) : empty);
    out.push_back(need[2 * i + 1] ? torch::empty_like(jacs[i]) : empty);
  }
  AT_DISPATCH_FLOATING_TYPES(pe.scalar_type(), "assemble_backward", [&] {
    std::vector<const scalar_t*> u, j;
    std::vector<scalar_t*> gu, gj;
    for (size_t i = 0; i < us.size(); ++i) {
      u.push_back(us[i].data_ptr<scalar_t>());
      j.push_back(jacs[i].data_ptr<scalar_t>());
      gu.push_back(need[2 * i] ? out[1 + 2 * i].data_ptr<scalar_t>() : nullptr);
      gj.push_back(need[2 * i + 1] ? out[2 + 2 * i].data_ptr<scalar_t>() : nullptr);
    }
    backward_rows<scalar_t>(pe.data_ptr<scalar_t>(), u, j, g.data_ptr<scalar_t>(),
                            need_pe ? out[0].data_ptr<scalar_t>() : nullptr, gu, gj, n, freqs.data_ptr<scalar_t>(), levels, Fs);
  });
  return out;
}

PYBIND11_MODULE(TORCH_EXTENSION_NAME, m) {
  m.def("positional_encode", &positional_encode, "gamma(x) for x (N, 3)");
  m.def("positional_adjoint", &positional_adjoint, "d L / d x from d L / d gamma(x) and gamma(x)");
  m.def("assemble_forward", &assemble_forward, "the SDF's spatial gradient from its parts");
  m.def("assemble_backward", &assemble_backward, "the adjoint of assemble_forward");
}
