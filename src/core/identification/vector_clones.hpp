// The swarm's vector loops and the statistics update are compiled twice on x86-64 with GCC: for
// AVX2 (four doubles per register) and for the baseline (SSE2, two); the loader picks the one the
// CPU runs (GCC's target_clones, through an ifunc). Neither clone enables FMA, so both give the same
// numbers. The random streams (integer work) get a third clone, for x86-64-v4. Elsewhere (Clang,
// ARM) the baseline alone.
//
// A cloned function is called through the loader's choice (an indirect call) and sets up each loop
// anew, so one step of the swarm is one cloned function; its helpers are PMSM_ALWAYS_INLINE
// (inlined into each clone, and compiled there for its instruction set).
#pragma once

#if defined(__x86_64__) && defined(__GNUC__) && !defined(__clang__) && defined(__linux__)
#define PMSM_VECTOR_CLONES __attribute__((target_clones("avx2", "default")))
// Integer work only (the random streams): a third clone for x86-64-v4, whose 64-bit rotate is one
// instruction where AVX2 needs two shifts and an or. (x86-64-v4 also brings FMA, which would let
// the compiler fuse a floating-point multiply and add: no function with a multiply may use this.)
#define PMSM_INTEGER_VECTOR_CLONES __attribute__((target_clones("arch=x86-64-v4", "avx2", "default")))
#else
#define PMSM_VECTOR_CLONES
#define PMSM_INTEGER_VECTOR_CLONES
#endif

#if defined(__GNUC__)
#define PMSM_ALWAYS_INLINE inline __attribute__((always_inline))
#else
#define PMSM_ALWAYS_INLINE inline
#endif
