// Flush-to-zero and denormals-are-zero for the calling thread and its OpenMP workers (the
// threads torch's parallel ops, MKL and oneDNN run on). `torch.set_flush_denormal` sets only the
// calling thread, so half of a 2-thread product kept the slow path. The setting is per thread
// and stays until changed: nicer_stream/denormals.py scopes it.
#include <torch/extension.h>
#include <omp.h>
#if defined(__x86_64__) || defined(__i386__)
#include <xmmintrin.h>
static const unsigned kFlags = 0x8040u;  // MXCSR bit 15 (FTZ) | bit 6 (DAZ)
static bool get_one() { return (_mm_getcsr() & kFlags) == kFlags; }
static void set_one(bool on) { unsigned c = _mm_getcsr(); _mm_setcsr(on ? (c | kFlags) : (c & ~kFlags)); }
static bool supported() { return true; }
#elif defined(__aarch64__)
static const uint64_t kFz = 1ull << 24;  // FPCR.FZ
static uint64_t fpcr() { uint64_t v; __asm__ __volatile__("mrs %0, fpcr" : "=r"(v)); return v; }
static bool get_one() { return (fpcr() & kFz) != 0; }
static void set_one(bool on) { uint64_t v = on ? (fpcr() | kFz) : (fpcr() & ~kFz); __asm__ __volatile__("msr fpcr, %0" : : "r"(v)); }
static bool supported() { return true; }
#else
static bool get_one() { return false; }
static void set_one(bool) {}
static bool supported() { return false; }
#endif

// Sets the flag on the calling thread and on every thread of its OpenMP team (the caller is
// thread 0 of the region); returns how many threads were set.
int64_t set_flush(bool on, int64_t threads) {
  int64_t count = 0;
#pragma omp parallel num_threads((int)threads) reduction(+ : count)
  {
    set_one(on);
    count += 1;
  }
  return count;
}

// The flag on the calling thread and on each thread of a region of `threads`, in thread order.
std::vector<bool> get_flush(int64_t threads) {
  std::vector<bool> out((size_t)threads, false);
#pragma omp parallel num_threads((int)threads)
  {
    int i = omp_get_thread_num();
    if (i < (int)threads) out[(size_t)i] = get_one();
  }
  return out;
}

PYBIND11_MODULE(TORCH_EXTENSION_NAME, m) {
  m.def("set_flush", &set_flush, "FTZ/DAZ on the calling thread and its OpenMP workers");
  m.def("get_flush", &get_flush, "FTZ/DAZ state of the calling thread and its OpenMP workers");
  m.def("supported", &supported, "whether this CPU architecture is handled");
}
