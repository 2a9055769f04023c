// Which vector unit the renderer's and the rasteriser's loops run on: one choice for both, the
// widest the CPU has and the caller allows (tests hold every unit to the same bits).
#pragma once

// The AVX-512 subsets the eight- and sixteen-lane paths use (AMD Zen 4 and 5, Intel since
// Skylake-SP). -ffp-contract=off (CMake) keeps the compiler from fusing their multiplies and
// adds: AVX-512 brings FMA, and a fused operation rounds once where the other paths round twice.
#define SIM_AVX512_TARGET "avx512f,avx512vl,avx512dq,avx512bw"

namespace sim {

enum class VectorUnit { kScalar, kAvx2, kAvx512 };

// `scalar`: no vector unit; `avx512` false: AVX2 at most.
inline VectorUnit vector_unit(bool scalar, bool avx512) {
  static const bool avx2 = __builtin_cpu_supports("avx2");
  static const bool avx512_subsets = __builtin_cpu_supports("avx512f") && __builtin_cpu_supports("avx512vl") &&
                                     __builtin_cpu_supports("avx512dq") && __builtin_cpu_supports("avx512bw");
  if (scalar || !avx2) return VectorUnit::kScalar;
  return avx512 && avx512_subsets ? VectorUnit::kAvx512 : VectorUnit::kAvx2;
}

}  // namespace sim
