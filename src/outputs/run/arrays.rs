//! The raw arrays of `spibench run` as `.npy` (in `arrays/`), so that the traced data can be
//! solved again elsewhere (deepinv, spyrit): the packed base patterns (`numpy.packbits` rows,
//! most significant bit first, as `spibench reconstruct` reads them), each scheme's
//! measurements and float reconstruction per ratio, the scope traces of the first frames, and
//! the transport maps. All float64, row-major, units in the names.

use crate::report::npy::{write_f64, write_u8};
use crate::report::output::OutputDir;
use crate::run::RunOutcome;

/// Writes the arrays into `out/arrays/` and returns their names.
pub fn write_arrays(o: &RunOutcome, out: &OutputDir) -> crate::Result<Vec<String>> {
    let t = &o.transport;
    let (w, h) = (t.units_across, t.units_down);
    let units = w * h;
    let mut files = Vec::new();
    let mut put = |name: String, shape: &[usize], data: &[f64]| -> crate::Result<()> {
        write_f64(&out.try_path(&format!("arrays/{name}"))?, shape, data)?;
        files.push(name);
        Ok(())
    };
    let m_max = o.results.iter().map(|r| r.measurements).max().unwrap_or(0);
    for r in &o.results {
        let tag = format!("{}_r{:.4}", r.scheme.key(), r.ratio);
        put(format!("measurements_{tag}_v.npy"), &[r.y.len()], &r.y)?;
        put(
            format!("reconstruction_{tag}.npy"),
            &[r.solution.height, r.solution.width],
            &r.solution.data,
        )?;
    }
    for (q, tr) in &o.traces {
        let n = tr.t_s.len();
        let mut data = tr.t_s.clone();
        for v in &tr.v {
            data.extend(v);
        }
        // Rows: time (s), RF, MONITOR+, MONITOR− (V).
        put(format!("scope_{}_s_v.npy", q.key()), &[4, n], &data)?;
    }
    put("transport_x_w.npy".into(), &[h, w], &t.x_w)?;
    put("transport_t_a.npy".into(), &[2, 2, h, w], &t.t_a)?;
    let g: Vec<f64> = t.g_a.iter().flatten().copied().collect();
    put("transport_g_a.npy".into(), &[2, h, w], &g)?;
    let k: Vec<f64> = t.k_map.iter().flatten().copied().collect();
    put("transport_k_a_per_w.npy".into(), &[2, h, w], &k)?;
    if m_max > 0 {
        let set = o.settings.patterns.build(w, h, m_max)?;
        let bits = set.base_patterns();
        let row_bytes = units.div_ceil(8);
        let mut packed = vec![0u8; m_max * row_bytes];
        for i in 0..m_max {
            for j in 0..units {
                if bits.get(i, j) {
                    packed[i * row_bytes + j / 8] |= 0x80 >> (j % 8);
                }
            }
        }
        write_u8(
            &out.try_path("arrays/patterns_packed.npy")?,
            &[m_max, row_bytes],
            &packed,
        )?;
        files.push("patterns_packed.npy".into());
    }
    Ok(files)
}
