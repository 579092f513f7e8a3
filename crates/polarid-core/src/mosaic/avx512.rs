//! The strip kernels compiled for AVX-512F (+ AVX2 + FMA), reached only with the
//! [`Avx512`](crate::cpu::Avx512) token (see `isa.rs`).

super::isa::entry_points!(crate::cpu::Avx512, "avx512f,avx2,fma");
