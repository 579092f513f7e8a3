//! The strip kernels compiled for AVX2 + FMA, reached only with the
//! [`Avx2Fma`](crate::cpu::Avx2Fma) token (see `isa.rs`).

super::isa::entry_points!(crate::cpu::Avx2Fma, "avx2,fma");
