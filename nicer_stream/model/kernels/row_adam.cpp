// Adam over the rows of a feature-grid table that have a gradient this step (a "lazy" Adam,
// as Instant-NGP skips hash entries whose gradient is exactly 0), then those gradient rows
// zeroed for the next backward. One pass reads the gradient (16 bytes a row for the fine grid);
// only the ~4% of rows a mapping iteration touches read and write their parameter and moments,
// where torch's fused Adam moves all seven arrays and a separate pass zeroes the gradient.
// Reference: nicer_stream/mapping/row_adam.py::row_adam_step_reference.
#include <torch/extension.h>
#include <cmath>
#include <cstdint>
#include <cstring>

// Whether a row has a non-zero entry, on the bit patterns (sign masked: -0 counts as 0, as in
// the reference's g != 0): integer ORs, where float compares were ~5x slower over a scan.
template <typename T> struct Bits;
template <> struct Bits<float> { using U = uint32_t; static constexpr U mag = 0x7fffffffu; };
template <> struct Bits<double> { using U = uint64_t; static constexpr U mag = 0x7fffffffffffffffull; };

// CW > 0: the row width known at compile time (the tables' 2, 4 and 32: loops unrolled and
// vectorised); CW == 0: any width `C`.
template <typename T, int64_t CW>
static int64_t step_rows(T* p, T* g, T* m, T* v, int64_t rows, int64_t C_any, double lr, double b1, double b2,
                         double eps, double bc1, double bc2, bool update) {
  using U = typename Bits<T>::U;
  const int64_t C = CW > 0 ? CW : C_any;
  const T step_size = (T)(lr / bc1), inv_sqrt_bc2 = (T)(1.0 / std::sqrt(bc2));
  const T tb1 = (T)b1, tb2 = (T)b2, te = (T)eps;
  int64_t touched = 0;
#pragma omp parallel for schedule(static) reduction(+ : touched)
  for (int64_t r = 0; r < rows; ++r) {
    T* gr = g + r * C;
    U acc = 0;
    for (int64_t c = 0; c < C; ++c) {
      U u;
      std::memcpy(&u, gr + c, sizeof(U));
      acc |= u & Bits<T>::mag;
    }
    if (acc == 0) continue;
    touched += 1;
    if (update) {
      T *pr = p + r * C, *mr = m + r * C, *vr = v + r * C;
      for (int64_t c = 0; c < C; ++c) {
        const T gc = gr[c];
        const T mc = tb1 * mr[c] + (1 - tb1) * gc, vc = tb2 * vr[c] + (1 - tb2) * gc * gc;
        mr[c] = mc;
        vr[c] = vc;
        pr[c] -= step_size * mc / (std::sqrt(vc) * inv_sqrt_bc2 + te);
      }
    }
    for (int64_t c = 0; c < C; ++c) gr[c] = (T)0;
  }
  return touched;
}

template <typename T>
static int64_t step_any_width(T* p, T* g, T* m, T* v, int64_t rows, int64_t C, double lr, double b1, double b2,
                              double eps, double bc1, double bc2, bool update) {
  switch (C) {
    case 2: return step_rows<T, 2>(p, g, m, v, rows, C, lr, b1, b2, eps, bc1, bc2, update);
    case 4: return step_rows<T, 4>(p, g, m, v, rows, C, lr, b1, b2, eps, bc1, bc2, update);
    case 32: return step_rows<T, 32>(p, g, m, v, rows, C, lr, b1, b2, eps, bc1, bc2, update);
    default: return step_rows<T, 0>(p, g, m, v, rows, C, lr, b1, b2, eps, bc1, bc2, update);
  }
}

// p, g, m, v: contiguous (rows, C) tensors of one dtype on the CPU; bc1, bc2: Adam's bias
// corrections 1 - beta^step. update=false only zeroes the touched gradient rows (a frozen group).
int64_t row_adam_step(torch::Tensor p, torch::Tensor g, torch::Tensor m, torch::Tensor v, double lr, double b1,
                      double b2, double eps, double bc1, double bc2, bool update) {
  TORCH_CHECK(p.dim() == 2 && p.sizes() == g.sizes() && p.sizes() == m.sizes() && p.sizes() == v.sizes(),
              "row_adam_step: p, g, m, v must be (rows, C) of one shape");
  TORCH_CHECK(p.is_contiguous() && g.is_contiguous() && m.is_contiguous() && v.is_contiguous(),
              "row_adam_step: contiguous tensors only");
  TORCH_CHECK(p.scalar_type() == g.scalar_type() && p.scalar_type() == m.scalar_type() &&
              p.scalar_type() == v.scalar_type(), "row_adam_step: one dtype");
  const int64_t rows = p.size(0), C = p.size(1);
  if (p.scalar_type() == torch::kFloat64)
    return step_any_width<double>(p.data_ptr<double>(), g.data_ptr<double>(), m.data_ptr<double>(), v.data_ptr<double>(),
                             rows, C, lr, b1, b2, eps, bc1, bc2, update);
  TORCH_CHECK(p.scalar_type() == torch::kFloat32, "row_adam_step: float32 or float64");
  return step_any_width<float>(p.data_ptr<float>(), g.data_ptr<float>(), m.data_ptr<float>(), v.data_ptr<float>(),
                          rows, C, lr, b1, b2, eps, bc1, bc2, update);
}

PYBIND11_MODULE(TORCH_EXTENSION_NAME, m) {
  m.def("row_adam_step", &row_adam_step, "Adam on the rows with a gradient, then those gradient rows zeroed");
}
