// The SDF's spatial gradient assembled from its parts in one pass over the points, and the
// adjoint of that assembly in one more (model/sdf_grad_assembly.py has the formulas and the
// tensor-op reference). Per point n, with P = 3 + 6L encoding columns laid out as
// [x (3), sin(f_l x_k) at 3 + 3l + k, cos(f_l x_k) at 3 + 3L + 3l + k], f_l = 2^l pi, and parts
// i = (u_i (N, P + F), J_i (N, 3, F)):
//   a = sum_i u_i[:, :P]
//   grad_k = a_k + sum_l f_l (cos_lk a_sin,lk - sin_lk a_cos,lk) + sum_i sum_f J_i[k, f] u_i[P + f]
// The tensor form takes ~25 autograd nodes and four (N, 3, F) temporaries per backward.
// -O3 with -ffp-contract=off, like the grid kernel; the contraction's sum over F is a vector
// reduction (`omp simd`), so its last bits depend on the CPU's vector width (tests use tolerances).
#include <torch/extension.h>
#include <algorithm>
#include <vector>

constexpr int64_t kRows = 256;  // rows per parallel chunk

// f_l = 2^l pi, in T.
template <typename T>
static std::vector<T> frequencies(int64_t levels) {
  std::vector<T> freqs(levels);
  for (int64_t l = 0; l < levels; ++l) freqs[l] = T(std::ldexp(M_PI, int(l)));
  return freqs;
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
                         T* grad, int64_t n, int64_t levels, const std::vector<int64_t>& Fs) {
  const int64_t P = 3 + 6 * levels;
  const std::vector<T> freqs = frequencies<T>(levels);
  parallel_rows(n, [&](int64_t c, int64_t end) {
    std::vector<T> a(P);
    for (int64_t r = c; r < end; ++r) {
      encoding_columns(u, Fs, r, P, a.data());
      const T* e = pe + r * P;
      for (int k = 0; k < 3; ++k) {
        T s = a[k];
        for (int64_t l = 0; l < levels; ++l) {
          const int64_t is = 3 + 3 * l + k, ic = 3 + 3 * levels + 3 * l + k;
          s += freqs[l] * (e[ic] * a[is] - e[is] * a[ic]);
        }
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
                          int64_t n, int64_t levels, const std::vector<int64_t>& Fs) {
  const int64_t P = 3 + 6 * levels;
  const std::vector<T> freqs = frequencies<T>(levels);
  parallel_rows(n, [&](int64_t c, int64_t end) {
    std::vector<T> a(P), ga(P);
    for (int64_t r = c; r < end; ++r) {
      const T* e = pe + r * P;
      const T g0 = g[r * 3], g1 = g[r * 3 + 1], g2 = g[r * 3 + 2];
      const T gk[3] = {g0, g1, g2};
      // d grad / d a: the same for every part's encoding columns.
      for (int k = 0; k < 3; ++k) ga[k] = gk[k];
      for (int64_t l = 0; l < levels; ++l)
        for (int k = 0; k < 3; ++k) {
          const int64_t is = 3 + 3 * l + k, ic = 3 + 3 * levels + 3 * l + k;
          ga[is] = gk[k] * freqs[l] * e[ic];
          ga[ic] = -gk[k] * freqs[l] * e[is];
        }
      if (g_pe) {
        encoding_columns(u, Fs, r, P, a.data());
        T* gp = g_pe + r * P;
        for (int k = 0; k < 3; ++k) gp[k] = 0;
        for (int64_t l = 0; l < levels; ++l)
          for (int k = 0; k < 3; ++k) {
            const int64_t is = 3 + 3 * l + k, ic = 3 + 3 * levels + 3 * l + k;
            gp[is] = -gk[k] * freqs[l] * a[ic];
            gp[ic] = gk[k] * freqs[l] * a[is];
          }
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

// pe (N, P); us: parts' u (N, P + F_i); jacs: parts' J (N, 3, F_i); all contiguous, one dtype.
torch::Tensor assemble_forward(torch::Tensor pe, std::vector<torch::Tensor> us, std::vector<torch::Tensor> jacs,
                               int64_t levels) {
  const int64_t n = pe.size(0);
  std::vector<int64_t> Fs;
  for (auto& t : jacs) Fs.push_back(t.size(2));
  auto grad = torch::empty({n, 3}, pe.options());
  AT_DISPATCH_FLOATING_TYPES(pe.scalar_type(), "assemble_forward", [&] {
    std::vector<const scalar_t*> u, j;
    for (auto& t : us) u.push_back(t.data_ptr<scalar_t>());
    for (auto& t : jacs) j.push_back(t.data_ptr<scalar_t>());
    forward_rows<scalar_t>(pe.data_ptr<scalar_t>(), u, j, grad.data_ptr<scalar_t>(), n, levels, Fs);
  });
  return grad;
}

// Returns [g_pe (or empty), g_u_0, g_jac_0, g_u_1, g_jac_1, ...]; a part's gradient is empty
// where `need` (per part: u, jac) says it is not needed.
std::vector<torch::Tensor> assemble_backward(torch::Tensor pe, std::vector<torch::Tensor> us,
                                             std::vector<torch::Tensor> jacs, torch::Tensor g, int64_t levels,
                                             bool need_pe, std::vector<bool> need) {
  const int64_t n = pe.size(0);
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
                            need_pe ? out[0].data_ptr<scalar_t>() : nullptr, gu, gj, n, levels, Fs);
  });
  return out;
}

PYBIND11_MODULE(TORCH_EXTENSION_NAME, m) {
  m.def("assemble_forward", &assemble_forward, "the SDF's spatial gradient from its parts");
  m.def("assemble_backward", &assemble_backward, "the adjoint of assemble_forward");
}
