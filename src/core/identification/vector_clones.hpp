// The swarm's vector loops are compiled twice on x86-64 with GCC: for AVX2 (four doubles per
// register) and for the baseline (SSE2, two); the loader picks the one the CPU runs (GCC's
// target_clones, through an ifunc). Neither clone enables FMA, so both give the same numbers.
// Elsewhere (Clang, ARM) the baseline alone.
#pragma once

#if defined(__x86_64__) && defined(__GNUC__) && !defined(__clang__) && defined(__linux__)
#define PMSM_VECTOR_CLONES __attribute__((target_clones("avx2", "default")))
#else
#define PMSM_VECTOR_CLONES
#endif
