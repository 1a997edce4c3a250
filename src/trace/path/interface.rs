//! What a path does at an interface: the chrome's sampled absorption, bulk absorption, and the
//! crossing of a dielectric interface (analogue or split), for the walk in [`super`].

use glam::DVec3;

use super::{Path, STREAM_SPAWNED, Walk, book};
use crate::optics::bench::Bench;
use crate::optics::fresnel::{reflect, refract};
use crate::optics::geometry::SURFACE_OFFSET;
use crate::trace::strata::PathRng;
use crate::trace::tally::{BatchTally, SLOT_SAMPLED};

/// What happens to a ray on chart chrome.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub(super) enum ChromeEvent {
    Reflected,
    Transmitted,
    Absorbed,
}

/// The lowest probability with which a ray on chrome is transmitted (see `chrome_event`).
pub(super) const CHROME_TRANSMIT_FLOOR: f64 = 0.02;

/// Chooses the fate of a ray on chrome of reflectance `rc` and transmittance `tc` from one
/// uniform `u`, and returns it with the fraction of the ray's weight that it keeps.
///
/// The expected outgoing power is exactly rc·w reflected and tc·w transmitted, as with a plain
/// weight of rc + tc, but the absorption is sampled: the ray reflects with probability rc (weight
/// unchanged), is transmitted with probability π_t = max(tc, 2 %) (weight × tc/π_t) and is
/// absorbed otherwise. With OD 3 chrome 97 % of the rays that meet chrome end there instead of
/// carrying 1e-3 of their weight through the rest of the bench at full cost, which is where most
/// of a weighted tracer's time went on a chart that is mostly chrome; the 2 % floor keeps the
/// light leaking through the chrome (part of the offsets b±) from resting on a few heavy rays.
/// No ray ever carries more than it had, so the ledger still balances ray by ray: what a ray
/// does not carry on is booked as absorbed by the chrome.
#[inline]
pub(super) fn chrome_event(rc: f64, tc: f64, u: f64) -> (ChromeEvent, f64) {
    let pt = if tc > 0.0 {
        tc.max(CHROME_TRANSMIT_FLOOR).min(1.0 - rc)
    } else {
        0.0
    };
    if u < rc {
        (ChromeEvent::Reflected, 1.0)
    } else if u < rc + pt {
        // min: 1 − R_c can round below T_c when the chrome absorbs nothing.
        (ChromeEvent::Transmitted, (tc / pt).min(1.0))
    } else {
        (ChromeEvent::Absorbed, 0.0)
    }
}

/// Bulk absorption over the last segment (length t) in medium `m`.
#[inline]
pub(super) fn attenuate(
    bench: &Bench,
    m: usize,
    t: f64,
    wl: f64,
    p: &mut Path,
    tally: &mut BatchTally,
) {
    if let Some((od, element)) = &bench.media()[m].absorption {
        let tau = 10f64.powf(-od.at(wl) * t);
        let kept = p.w * tau;
        tally.ledger[p.world][*element] += p.w - kept;
        p.w = kept;
    }
}

/// A path crossing a dielectric interface of reflectance `r` from index n1 into n2 (normal `nn`
/// facing the incoming ray).
///
/// With the analogue tracer ([`Sampling::Independent`], [`Sampling::Stratified`]) the path
/// reflects with probability r and refracts otherwise, its weight unchanged ([`scatter`]).
///
/// With [`Sampling::Split`] the path always refracts, carrying w·(1 − r), and the reflected part
/// (expected weight w·r) is followed as a path of its own with probability r at the full weight
/// w. Both parts have the analogue expectation, so every tally stays unbiased, but the light that
/// crosses all the interfaces of the bench (the signal) is no longer a coin toss per interface:
/// the estimate of k± needs about half the rays for the same error (docs/tracer_sampling.md).
/// The reflected path's weight is w rather than w·r, so the traced weight no longer balances ray
/// by ray: the difference (w − w·r when the reflected path is followed, −w·r when it is not,
/// zero in expectation) is booked to the ledger's `SLOT_SAMPLED`, and the ledger balances
/// exactly with it.
#[allow(clippy::too_many_arguments)]
#[inline]
pub(super) fn cross_interface(
    ctx: &Walk,
    p: &mut Path,
    hit: DVec3,
    nn: DVec3,
    (n1, n2, r): (f64, f64, f64),
    rng: &mut PathRng,
    tally: &mut BatchTally,
    stack: &mut Vec<Path>,
) {
    if !ctx.split_reflections {
        scatter(p, hit, nn, n1, n2, r, rng);
        return;
    }
    let refracted = if r >= 1.0 {
        None
    } else {
        refract(p.d, nn, n1, n2)
    };
    let Some(d) = refracted else {
        // Total internal reflection (or a perfect reflector): all of it reflects.
        p.d = reflect(p.d, nn);
        p.o = hit + SURFACE_OFFSET * nn;
        return;
    };
    let reflected = p.w * r;
    if reflected > 0.0 {
        let slot = ctx.bench.elements().len() + SLOT_SAMPLED;
        if rng.uniform() < r {
            let n = ctx.spawned.get();
            ctx.spawned.set(n + 1);
            let mut q = *p;
            q.d = reflect(p.d, nn);
            q.o = hit + SURFACE_OFFSET * nn;
            q.fresh_stream = Some(STREAM_SPAWNED + n);
            book(tally, p.world, slot, p.w - reflected);
            stack.push(q);
        } else {
            book(tally, p.world, slot, -reflected);
        }
    }
    p.w -= reflected;
    p.d = d;
    p.o = hit - SURFACE_OFFSET * nn;
}

/// Reflect with probability `r`, else refract from n1 into n2 (normal `nn` faces the incoming
/// ray). The ray leaves from `hit`, offset to its outgoing side.
#[inline]
pub(super) fn scatter(
    p: &mut Path,
    hit: DVec3,
    nn: DVec3,
    n1: f64,
    n2: f64,
    r: f64,
    rng: &mut PathRng,
) {
    let refracted = if r >= 1.0 || rng.uniform() < r {
        None
    } else {
        refract(p.d, nn, n1, n2)
    };
    match refracted {
        Some(d) => {
            p.d = d;
            p.o = hit - SURFACE_OFFSET * nn;
        }
        None => {
            p.d = reflect(p.d, nn);
            p.o = hit + SURFACE_OFFSET * nn;
        }
    }
}
