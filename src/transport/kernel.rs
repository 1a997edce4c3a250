//! The transport of an object from a traced object kernel (`trace::kernel`): a sparse product
//! instead of a trace.

use super::{Estimate, Ledger, Transport, TransportParts, UnitMoments, batch_factor};
use crate::error::{Error, Result};
use crate::optics::{Arm, Bench};
use crate::trace::kernel::{Kernel, PV_X, pv_c, pv_g};

impl Transport {
    /// The transport of `object` (transmittance per pixel of `kernel.grid`, row-major) through
    /// the bench whose kernel was traced. Ambient and dark currents come from `bench`'s
    /// detectors; the ledger is that of the kernel's clear-chart trace. Standard errors treat
    /// the pixels of a batch as independent (see `trace::kernel`); the per-unit maps and their
    /// guards are those of [`Transport::from_tallies`] (`Transport::assemble`), except that the
    /// kernel's centred moments cannot show a unit lit in one batch alone.
    pub fn from_kernel(bench: &Bench, kernel: &Kernel, object: &[f64]) -> Result<Transport> {
        Transport::from_kernel_with(bench, kernel, object, false, true)
    }

    /// [`Transport::from_kernel`] through the kernel's linear part ([`Kernel::apply_linear`]:
    /// paths that met the chart more than once weighted by their first pixel alone), the model
    /// of the linear operator `pipeline::operator`.
    pub fn from_kernel_linear(bench: &Bench, kernel: &Kernel, object: &[f64]) -> Result<Transport> {
        Transport::from_kernel_with(bench, kernel, object, true, true)
    }

    /// [`Transport::from_kernel`] (`linear`: [`Transport::from_kernel_linear`]) for users that
    /// read only its values (a dataset sample, a Python measurement): every value is the same,
    /// the per-unit maps' standard errors too, but the totals' (k±, k′, imbalance, c±, x) are
    /// NaN, as for an unresolved trace ([`Kernel::apply_values`]: a third of the time of a
    /// 96 × 96 product, and most of its memory traffic, which bounds many-thread datasets).
    pub fn from_kernel_values(
        bench: &Bench,
        kernel: &Kernel,
        object: &[f64],
        linear: bool,
    ) -> Result<Transport> {
        Transport::from_kernel_with(bench, kernel, object, linear, false)
    }

    fn from_kernel_with(
        bench: &Bench,
        kernel: &Kernel,
        object: &[f64],
        linear: bool,
        errors: bool,
    ) -> Result<Transport> {
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
        let p = match (errors, linear) {
            (false, _) => kernel.apply_values(object, linear),
            (true, true) => kernel.apply_linear(object),
            (true, false) => kernel.apply(object),
        };
        // A single batch has no spread to measure (see `batch_factor`): NaN, as the batch-means
        // estimates of a trace's tallies give; so are the totals' errors not summed.
        let resolved = errors && batch_factor(p.batches).is_some();
        let total = |a: usize| Estimate {
            value: p.sums[a],
            stderr: if resolved {
                p.cov(a, a).max(0.0).sqrt()
            } else {
                f64::NAN
            },
        };
        // Delta method for ΣA/ΣD with A = Σ αₐ vₐ and D = Σ δₐ vₐ.
        let ratio = |num: &[(usize, f64)], den: &[(usize, f64)]| {
            let lin = |w: &[(usize, f64)]| w.iter().map(|&(a, c)| c * p.sums[a]).sum::<f64>();
            let (a, dd) = (lin(num), lin(den));
            let r = a / dd;
            if !resolved {
                return Estimate {
                    value: r,
                    stderr: f64::NAN,
                };
            }
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
        let (g_plus, g_minus) = (pv_g(Arm::Plus), pv_g(Arm::Minus));
        let k = Arm::ALL.map(|arm| ratio(&[(pv_g(arm), 1.0)], &[(PV_X, 1.0)]));
        let k_prime = ratio(&[(g_plus, 1.0), (g_minus, 1.0)], &[(PV_X, 1.0)]);
        let imbalance = ratio(
            &[(g_plus, 1.0), (g_minus, -1.0)],
            &[(g_plus, 1.0), (g_minus, 1.0)],
        );
        Ok(Transport::assemble(
            bench,
            TransportParts {
                rays: kernel.rays,
                seed: kernel.seed,
                units_across: kernel.units_across,
                units_down: kernel.units_down,
                batches: p.batches,
                t_a: p.t.clone(),
                x_w: p.x.clone(),
                moments: UnitMoments {
                    g2: &p.g2,
                    gx: &p.gx,
                    x2: &p.x2,
                    raw: false,
                },
                c_traced: Arm::ALL.map(|arm| total(pv_c(arm))),
                x_total: total(PV_X),
                k,
                k_prime,
                imbalance,
                ledger: Ledger::from_tallies(bench, &kernel.tallies),
            },
        ))
    }

    /// The standard errors of the per-unit gains g±_j of a transport made by
    /// [`Transport::from_kernel`] are not kept in `Transport`; this gives them (A).
    pub fn kernel_gain_stderr(kernel: &Kernel, object: &[f64]) -> [Vec<f64>; 2] {
        let p = kernel.apply(object);
        match batch_factor(p.batches) {
            Some(bfac) => Arm::ALL.map(|arm| {
                p.g2[arm]
                    .iter()
                    .map(|v| (v.max(0.0) * bfac).sqrt())
                    .collect()
            }),
            // A single batch: unresolved, as `Transport::k_map_stderr`.
            None => Arm::ALL.map(|arm| vec![f64::INFINITY; p.g2[arm].len()]),
        }
    }
}
