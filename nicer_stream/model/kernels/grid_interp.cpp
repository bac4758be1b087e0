// Trilinear interpolation of multi-level feature grids (dense or spatially hashed levels)
// with the spatial Jacobian, forward and backward, for the CPU. One pass per point and
// level replaces ~30 tensor ops of the reference (model/dense_grid.py, model/hash_grid.py).
// Conventions are the reference's: u = (clamp(x, -1, 1) + 1) * (r - 1) / 2,
// i0 = min(max(floor(u), 0), r - 2), corner k = 4 bx + 2 by + bz, dense row
// (ix * r + iy) * r + iz, hashed row (ix ^ iy * 2654435761 ^ iz * 805459861) mod size.
#include <torch/extension.h>
#include <algorithm>
#include <type_traits>
#include <vector>
#include <cmath>

namespace {

struct Level {
  int64_t res, offset, size;  // size: rows of the level (hash modulus when hashed)
  bool hashed, pow2;
};

template <typename scalar_t>
struct Cell {
  int64_t rows[8];
  scalar_t w[8], dw[3][8];  // weights and d w / d frac_a
  scalar_t frac[3], scale;
  bool inside[3];           // |x_a| <= 1: the clamp passes the gradient
};

template <typename scalar_t>
inline void make_cell(const scalar_t* x, const Level& lv, Cell<scalar_t>& c) {
  c.scale = scalar_t(lv.res - 1) / 2;
  int64_t i0[3];
  for (int a = 0; a < 3; ++a) {
    scalar_t xa = x[a];
    c.inside[a] = xa >= -1 && xa <= 1;
    xa = xa < -1 ? -1 : (xa > 1 ? 1 : xa);
    scalar_t u = (xa + 1) * c.scale;
    int64_t i = (int64_t)std::floor(u);
    i = i < 0 ? 0 : i;
    i = i > lv.res - 2 ? lv.res - 2 : i;
    i0[a] = i;
    c.frac[a] = u - scalar_t(i);
  }
  for (int k = 0; k < 8; ++k) {
    int64_t b[3] = {(k >> 2) & 1, (k >> 1) & 1, k & 1};
    int64_t ix = i0[0] + b[0], iy = i0[1] + b[1], iz = i0[2] + b[2];
    int64_t row;
    if (lv.hashed) {
      uint64_t h = (uint64_t)ix ^ ((uint64_t)iy * 2654435761ULL) ^ ((uint64_t)iz * 805459861ULL);
      row = (int64_t)(lv.pow2 ? (h & (uint64_t)(lv.size - 1)) : (h % (uint64_t)lv.size));
    } else {
      row = (ix * lv.res + iy) * lv.res + iz;
    }
    c.rows[k] = row + lv.offset;
    scalar_t f[3], s[3];
    for (int a = 0; a < 3; ++a) {
      f[a] = b[a] ? c.frac[a] : 1 - c.frac[a];
      s[a] = b[a] ? 1 : -1;
    }
    c.w[k] = f[0] * f[1] * f[2];
    c.dw[0][k] = s[0] * f[1] * f[2];
    c.dw[1][k] = f[0] * s[1] * f[2];
    c.dw[2][k] = f[0] * f[1] * s[2];
  }
}

std::vector<Level> levels_of(const torch::Tensor& res, const torch::Tensor& offsets,
                             const torch::Tensor& sizes, const torch::Tensor& hashed) {
  auto r = res.accessor<int64_t, 1>();
  auto o = offsets.accessor<int64_t, 1>();
  auto s = sizes.accessor<int64_t, 1>();
  auto h = hashed.accessor<bool, 1>();
  std::vector<Level> lv(r.size(0));
  for (int64_t l = 0; l < r.size(0); ++l) lv[l] = {r[l], o[l], s[l], h[l], (s[l] & (s[l] - 1)) == 0};
  return lv;
}

// For each point, first its cell on every level is computed and the cells' table rows
// prefetched, then the rows are read. The reads are random (a table is tens of MB): one level at
// a time, each waited for its own misses; with all levels' rows requested together the misses
// overlap (docs/performance.md: 2x on the fine grid and the colour hash, forward and backward;
// blocks of 1, 4, 8 and 16 points per prefetch measured the same, so it is one point). `CC` is the
// channel count when it is known at compile time (the model's 2, 4 and 32), else 0 and read at
// run time (no measurable gain on its own, kept for the unrolled channel loops).

template <typename scalar_t>
inline void prefetch_rows(const scalar_t* T, const Cell<scalar_t>& c, int64_t C) {
  for (int k = 0; k < 8; ++k) __builtin_prefetch(T + c.rows[k] * C);
}

// Point n's cell on every level into cells[0..L), its rows prefetched from T unless T is null.
template <typename scalar_t>
inline void point_cells(const scalar_t* X, const std::vector<Level>& lv, int64_t n,
                        Cell<scalar_t>* cells, const scalar_t* T, int64_t C) {
  for (size_t l = 0; l < lv.size(); ++l) {
    make_cell(X + 3 * n, lv[l], cells[l]);
    if (T) prefetch_rows(T, cells[l], C);
  }
}

template <typename scalar_t, int CC>
void forward_impl(const scalar_t* T, const scalar_t* X, scalar_t* O, scalar_t* J,
                  const std::vector<Level>& lv, int64_t N, int64_t C_rt) {
  const int64_t C = CC > 0 ? CC : C_rt, L = lv.size(), LC = L * C;
  at::parallel_for(0, N, 256, [&](int64_t begin, int64_t end) {
    std::vector<Cell<scalar_t>> cells(L);
    for (int64_t n = begin; n < end; ++n) {
      point_cells(X, lv, n, cells.data(), T, C);
      for (int64_t l = 0; l < L; ++l) {
        const Cell<scalar_t>& c = cells[l];
        scalar_t* o = O + n * LC + l * C;
        scalar_t* j[3] = {nullptr, nullptr, nullptr};
        for (int64_t ch = 0; ch < C; ++ch) o[ch] = 0;
        if (J) for (int a = 0; a < 3; ++a) {
          j[a] = J + (n * 3 + a) * LC + l * C;
          for (int64_t ch = 0; ch < C; ++ch) j[a][ch] = 0;
        }
        for (int k = 0; k < 8; ++k) {
          const scalar_t* t = T + c.rows[k] * C;
          for (int64_t ch = 0; ch < C; ++ch) o[ch] += c.w[k] * t[ch];
          if (J) for (int a = 0; a < 3; ++a) {
            const scalar_t d = c.dw[a][k] * c.scale;
            for (int64_t ch = 0; ch < C; ++ch) j[a][ch] += d * t[ch];
          }
        }
      }
    }
  });
}

// g_x of one (point, level) cell: d/dx of <g_out, out> + <g_jac, jac>, before the clamp.
template <typename scalar_t, int CC>
inline void cell_grad_x(const Cell<scalar_t>& c, const scalar_t* T, const scalar_t* go,
                        const scalar_t* const* gj, int64_t C_rt, scalar_t* gf_total) {
  const int64_t C = CC > 0 ? CC : C_rt;
  scalar_t gf[3] = {0, 0, 0};
  for (int k = 0; k < 8; ++k) {
    const scalar_t* t = T + c.rows[k] * C;
    scalar_t dot_go = 0;
    for (int64_t ch = 0; ch < C; ++ch) dot_go += t[ch] * go[ch];
    for (int b = 0; b < 3; ++b) gf[b] += c.dw[b][k] * dot_go;
    if (gj[0]) {
      // jac_a = scale * sum_k dw_a,k t_k; d dw_a,k / d frac_b (b != a) = s_a s_b f_other.
      const int bits[3] = {(k >> 2) & 1, (k >> 1) & 1, k & 1};
      for (int a = 0; a < 3; ++a) {
        scalar_t dot_gj = 0;
        for (int64_t ch = 0; ch < C; ++ch) dot_gj += t[ch] * gj[a][ch];
        for (int b = 0; b < 3; ++b) {
          if (b == a) continue;
          const int o = 3 - a - b;
          const scalar_t sa = bits[a] ? 1 : -1, sb = bits[b] ? 1 : -1;
          const scalar_t fo = bits[o] ? c.frac[o] : 1 - c.frac[o];
          gf[b] += c.scale * sa * sb * fo * dot_gj;
        }
      }
    }
  }
  for (int b = 0; b < 3; ++b) gf_total[b] += c.inside[b] ? gf[b] * c.scale : 0;
}

// The table's gradient, level by level: each (point, level) cell's 8 rows get
// w_k g_out + scale (dw_k . g_jac) added, in point order. The rows are random, so the cell of
// the point `kAhead` places on is computed first and its rows prefetched for writing (a ring of
// cells). Threads own whole levels (interleaved, so that the large fine levels are shared out),
// or, with fewer levels than threads, the rows with row mod T == t (T a power of two).
// Deterministic for a given thread count, without atomics: every row is updated by one thread.
// (One pass: a buffer of all (point, level, corner) contributions would be 25 MB per call for
// the fine grid.)
template <typename scalar_t, int CC>
void scatter_table(const scalar_t* X, const scalar_t* GO, const scalar_t* GJ, scalar_t* TG,
                   const std::vector<Level>& lv, int64_t N, int64_t C_rt) {
  const int64_t C = CC > 0 ? CC : C_rt, L = lv.size(), LC = L * C;
  constexpr int64_t kAhead = 8;
  auto run = [&](int64_t l, int64_t mask, int64_t owner) {
    const Level& lev = lv[l];
    Cell<scalar_t> ring[kAhead];
    for (int64_t n = 0; n < std::min(kAhead, N); ++n) {
      make_cell(X + 3 * n, lev, ring[n]);
      for (int k = 0; k < 8; ++k) __builtin_prefetch(TG + ring[n].rows[k] * C, 1);
    }
    for (int64_t n = 0; n < N; ++n) {
      const Cell<scalar_t> c = ring[n % kAhead];
      if (n + kAhead < N) {
        Cell<scalar_t>& next = ring[n % kAhead];
        make_cell(X + 3 * (n + kAhead), lev, next);
        for (int k = 0; k < 8; ++k) __builtin_prefetch(TG + next.rows[k] * C, 1);
      }
      const scalar_t* go = GO + n * LC + l * C;
      const scalar_t* gj[3] = {nullptr, nullptr, nullptr};
      if (GJ) for (int a = 0; a < 3; ++a) gj[a] = GJ + (n * 3 + a) * LC + l * C;
      for (int k = 0; k < 8; ++k) {
        const int64_t row = c.rows[k];
        if ((row & mask) != owner) continue;
        scalar_t* tg = TG + row * C;
        for (int64_t ch = 0; ch < C; ++ch) {
          scalar_t v = c.w[k] * go[ch];
          if (GJ) v += c.scale * (c.dw[0][k] * gj[0][ch] + c.dw[1][k] * gj[1][ch] + c.dw[2][k] * gj[2][ch]);
          tg[ch] += v;
        }
      }
    }
  };
  const int64_t threads = std::max<int64_t>(1, std::min<int64_t>(at::get_num_threads(), N / 1024 + 1));
  if (L >= threads) {
    at::parallel_for(0, threads, 1, [&](int64_t first, int64_t last) {
      for (int64_t t = first; t < last; ++t)
        for (int64_t l = t; l < L; l += threads) run(l, 0, 0);
    });
  } else {
    int64_t n_owner = 1;
    while (n_owner * 2 <= threads) n_owner *= 2;
    at::parallel_for(0, n_owner, 1, [&](int64_t first, int64_t last) {
      for (int64_t owner = first; owner < last; ++owner)
        for (int64_t l = 0; l < L; ++l) run(l, n_owner - 1, owner);
    });
  }
}

// The points' gradients (parallel over points; rows prefetched as in the forward).
template <typename scalar_t, int CC>
void grad_points(const scalar_t* T, const scalar_t* X, const scalar_t* GO, const scalar_t* GJ,
                 scalar_t* GX, const std::vector<Level>& lv, int64_t N, int64_t C_rt) {
  const int64_t C = CC > 0 ? CC : C_rt, L = lv.size(), LC = L * C;
  at::parallel_for(0, N, 256, [&](int64_t begin, int64_t end) {
    std::vector<Cell<scalar_t>> cells(L);
    for (int64_t n = begin; n < end; ++n) {
      point_cells(X, lv, n, cells.data(), T, C);
      scalar_t gf_total[3] = {0, 0, 0};
      for (int64_t l = 0; l < L; ++l) {
        const scalar_t* go = GO + n * LC + l * C;
        const scalar_t* gj[3] = {nullptr, nullptr, nullptr};
        if (GJ) for (int a = 0; a < 3; ++a) gj[a] = GJ + (n * 3 + a) * LC + l * C;
        cell_grad_x<scalar_t, CC>(cells[l], T, go, gj, C, gf_total);
      }
      for (int b = 0; b < 3; ++b) GX[3 * n + b] = gf_total[b];
    }
  });
}

template <typename scalar_t, int CC>
void backward_impl(const scalar_t* T, const scalar_t* X, const scalar_t* GO, const scalar_t* GJ,
                   scalar_t* TG, scalar_t* GX, const std::vector<Level>& lv, int64_t N, int64_t C_rt) {
  if (GX) grad_points<scalar_t, CC>(T, X, GO, GJ, GX, lv, N, C_rt);
  if (TG) scatter_table<scalar_t, CC>(X, GO, GJ, TG, lv, N, C_rt);
}

// Calls f<CC>() with the compile-time channel count for the model's tables, else CC = 0.
template <typename F>
void with_channels(int64_t C, F&& f) {
  switch (C) {
    case 2: f(std::integral_constant<int, 2>()); break;
    case 4: f(std::integral_constant<int, 4>()); break;
    case 32: f(std::integral_constant<int, 32>()); break;
    default: f(std::integral_constant<int, 0>());
  }
}

}  // namespace

// table (R, C), x (N, 3) -> out (N, L*C), jac (N, 3, L*C) (empty unless with_jac)
std::vector<torch::Tensor> grid_forward(torch::Tensor table, torch::Tensor x, torch::Tensor res,
                                        torch::Tensor offsets, torch::Tensor sizes, torch::Tensor hashed,
                                        bool with_jac) {
  auto lv = levels_of(res, offsets, sizes, hashed);
  const int64_t N = x.size(0), C = table.size(1), L = lv.size();
  auto out = torch::empty({N, L * C}, table.options());
  auto jac = with_jac ? torch::empty({N, 3, L * C}, table.options()) : torch::empty({0}, table.options());
  AT_DISPATCH_FLOATING_TYPES(table.scalar_type(), "grid_forward", [&] {
    with_channels(C, [&](auto cc) {
      forward_impl<scalar_t, decltype(cc)::value>(table.data_ptr<scalar_t>(), x.data_ptr<scalar_t>(),
                                                  out.data_ptr<scalar_t>(), with_jac ? jac.data_ptr<scalar_t>() : nullptr,
                                                  lv, N, C);
    });
  });
  return {out, jac};
}

// Gradients of grid_forward given g_out (N, L*C) and g_jac (N, 3, L*C) or empty.
// Adds the table's gradient into table_grad (R, C) when it is defined; returns g_x (N, 3)
// (zeros unless need_x).
torch::Tensor grid_backward(torch::Tensor table, torch::Tensor x, torch::Tensor res, torch::Tensor offsets,
                            torch::Tensor sizes, torch::Tensor hashed, torch::Tensor g_out, torch::Tensor g_jac,
                            torch::Tensor table_grad, bool need_x) {
  auto lv = levels_of(res, offsets, sizes, hashed);
  const int64_t N = x.size(0), C = table.size(1);
  const bool has_jac = g_jac.numel() > 0, need_table = table_grad.defined() && table_grad.numel() > 0;
  auto g_x = torch::zeros({N, 3}, x.options());
  if (!need_table && !need_x) return g_x;
  AT_DISPATCH_FLOATING_TYPES(table.scalar_type(), "grid_backward", [&] {
    with_channels(C, [&](auto cc) {
      backward_impl<scalar_t, decltype(cc)::value>(
          table.data_ptr<scalar_t>(), x.data_ptr<scalar_t>(), g_out.data_ptr<scalar_t>(),
          has_jac ? g_jac.data_ptr<scalar_t>() : nullptr, need_table ? table_grad.data_ptr<scalar_t>() : nullptr,
          need_x ? g_x.data_ptr<scalar_t>() : nullptr, lv, N, C);
    });
  });
  return g_x;
}

PYBIND11_MODULE(TORCH_EXTENSION_NAME, m) {
  m.def("grid_forward", &grid_forward, "multi-level trilinear grid interpolation (+ Jacobian)");
  m.def("grid_backward", &grid_backward, "its backward");
}
