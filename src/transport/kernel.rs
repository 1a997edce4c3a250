//! The transport of an object from a traced object kernel (`trace::kernel`): a sparse product
//! instead of a trace.

use super::{Estimate, Ledger, Transport};
use crate::error::{Error, Result};
use crate::optics::Bench;
use crate::trace::kernel::Kernel;

/// Component indices of the kernel's per-pixel vector (g₊, g₋, x, c₊, c₋).
const G0: usize = 0;
const G1: usize = 1;
const X: usize = 2;
const C0: usize = 3;
const C1: usize = 4;

impl Transport {
    /// The transport of `object` (transmittance per pixel of `kernel.grid`, row-major) through
    /// the bench whose kernel was traced. Ambient and dark currents come from `bench`'s
    /// detectors; the ledger is that of the kernel's clear-chart trace. Standard errors treat
    /// the pixels of a batch as independent (see `trace::kernel`).
    pub fn from_kernel(bench: &Bench, kernel: &Kernel, object: &[f64]) -> Result<Transport> {
        if object.len() != kernel.grid.pixels() {
            return Err(Error::field(
                "object",
                format!(
                    "an object of {} pixels for a kernel grid of {}×{}",
                    object.len(),
                    kernel.grid.width_px,
                    kernel.grid.height_px
                ),
            ));
        }
        if (bench.units_shape()) != (kernel.units_across, kernel.units_down) {
            return Err(Error::field(
                "kernel",
                "the kernel was traced for another pattern area",
            ));
        }
        let p = kernel.apply(object);
        let units = kernel.units();
        let nb = p.batches as f64;
        let bfac = if nb >= 2.0 { nb / (nb - 1.0) } else { f64::NAN };
        let idx = |d: usize, s: usize, j: usize| (d * 2 + s) * units + j;
        let g_a: [Vec<f64>; 2] = [0, 1].map(|d| {
            (0..units)
                .map(|j| p.t[idx(d, d, j)] - p.t[idx(d, 1 - d, j)])
                .collect()
        });
        let mut k_map = [vec![0.0; units], vec![0.0; units]];
        let mut k_map_stderr = [vec![0.0; units], vec![0.0; units]];
        for d in 0..2 {
            for j in 0..units {
                let x = p.x[j];
                if x > 0.0 {
                    let k = g_a[d][j] / x;
                    k_map[d][j] = k;
                    let q = p.g2[d][j] - 2.0 * k * p.gx[d][j] + k * k * p.x2[j];
                    k_map_stderr[d][j] = (q.max(0.0) * bfac).sqrt() / x;
                }
            }
        }
        let ambient_a = [0, 1].map(|d| bench.detectors()[d].ambient_current_a);
        let dark_a = [0, 1].map(|d| bench.detectors()[d].dark_current_a);
        let total = |a: usize| Estimate {
            value: p.sums[a],
            stderr: p.cov(a, a).max(0.0).sqrt(),
        };
        // Delta method for ΣA/ΣD with A = Σ αₐ vₐ and D = Σ δₐ vₐ.
        let ratio = |num: &[(usize, f64)], den: &[(usize, f64)]| {
            let lin = |w: &[(usize, f64)]| w.iter().map(|&(a, c)| c * p.sums[a]).sum::<f64>();
            let (a, dd) = (lin(num), lin(den));
            let r = a / dd;
            // Var(A − r D) = Σ_ab u_a u_b cov(a, b), u = α − r δ.
            let mut u = [0.0; 5];
            for &(a, c) in num {
                u[a] += c;
            }
            for &(a, c) in den {
                u[a] -= r * c;
            }
            let mut v = 0.0;
            for a in 0..5 {
                for b in 0..5 {
                    v += u[a] * u[b] * p.cov(a, b);
                }
            }
            Estimate {
                value: r,
                stderr: v.max(0.0).sqrt() / dd.abs(),
            }
        };
        let c_traced = [total(C0), total(C1)];
        let x_total = total(X);
        let c_a = [0, 1].map(|d| c_traced[d].value + ambient_a[d] + dark_a[d]);
        let b = [0, 1].map(|d| Estimate {
            value: c_a[d],
            stderr: c_traced[d].stderr,
        });
        let k = [
            ratio(&[(G0, 1.0)], &[(X, 1.0)]),
            ratio(&[(G1, 1.0)], &[(X, 1.0)]),
        ];
        let k_prime = ratio(&[(G0, 1.0), (G1, 1.0)], &[(X, 1.0)]);
        let imbalance = ratio(&[(G0, 1.0), (G1, -1.0)], &[(G0, 1.0), (G1, 1.0)]);
        let (x_w, t_a) = (p.x.clone(), p.t.clone());
        Ok(Transport {
            rays: kernel.rays,
            seed: kernel.seed,
            units_across: kernel.units_across,
            units_down: kernel.units_down,
            x_w,
            t_a,
            g_a,
            k_map,
            k_map_stderr,
            c_a,
            c_traced,
            ambient_a,
            dark_a,
            x_total,
            k,
            b,
            k_prime,
            imbalance,
            ledger: Ledger::from_tallies(bench, &kernel.tallies),
        })
    }

    /// The standard errors of the per-unit gains g±_j of a transport made by
    /// [`Transport::from_kernel`] are not kept in `Transport`; this gives them (A).
    pub fn kernel_gain_stderr(kernel: &Kernel, object: &[f64]) -> [Vec<f64>; 2] {
        let p = kernel.apply(object);
        let nb = p.batches as f64;
        let bfac = nb / (nb - 1.0);
        [0, 1].map(|d| p.g2[d].iter().map(|v| (v.max(0.0) * bfac).sqrt()).collect())
    }
}
