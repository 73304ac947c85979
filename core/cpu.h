// Instruction-set dispatch for the few kernels that have an AVX2 form besides the baseline
// (SSE2) one: the paint kernel of the simulator's sweep, batchExp, randomBitsBatch. Every
// AVX2 form performs the baseline form's operations lane by lane (no fused multiply-add), so
// results are the same bits on any x86-64 processor; the AVX2 forms only run faster.
#pragma once

namespace eco {

#if defined(__GNUC__) && defined(__x86_64__)
#define ECO_HAVE_AVX2_KERNELS 1
#define ECO_TARGET_AVX2 __attribute__((target("avx2")))

/// Whether the kernels use their AVX2 forms: by default when the processor has AVX2.
bool avx2Kernels();
/// Turns the AVX2 forms on (where the processor has AVX2) or off; returns whether they are
/// now on. For tests and comparisons; not thread-safe (call between runs).
bool setAvx2Kernels(bool on);
#else
inline bool avx2Kernels() { return false; }
inline bool setAvx2Kernels(bool) { return false; }
#endif

}  // namespace eco
