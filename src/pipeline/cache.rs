//! The trace cache: a trace stored on disk, keyed by what determines it, so that a change of
//! electronics, solver or noise settings reuses the trace instead of repeating it.
//!
//! **Key.** SHA-256 of the canonical bench (its RON as [`crate::scene::doc::to_ron`] writes it:
//! every field, defaults filled in; the `electronics:` and `run:` sections are left out because
//! the trace does not read them), the bytes of every image the bench loads (a chart mask), the
//! number of rays, the seed, the spibench version and [`TRACER_REVISION`]. Any change to one of
//! them is a new key.
//!
//! **Entry.** One file `KEY.trace`: a magic string, the format version, the key, the payload
//! length, the payload's SHA-256 and the payload (the merged tallies, little-endian). It is
//! written under a temporary name and renamed into place, so a reader never sees half a file.
//! An entry whose header, length or checksum does not match is reported as corrupt and rebuilt,
//! never trusted.
//!
//! **Untrusted folder.** The cache folder is named by the user, but what it holds may have been
//! put there by anyone (crate::report::untrusted): an entry's name is made here from the key,
//! never read from the folder, and an entry that is not a plain file (a symbolic link, which
//! could lead out of the folder, or a folder) is not opened: it is reported as corrupt, and
//! storing the rebuilt entry replaces the link itself, not what it points to.

use std::path::{Path, PathBuf};

use sha2::{Digest, Sha256};

use crate::provenance::hex;

use crate::error::{Error, Result};
use crate::scene::bench::{ChartPatternSpec, ChartSpec, ElementSpec};
use crate::scene::doc::BenchDoc;
use crate::trace::{BatchScalars, Tallies};

const MAGIC: &[u8; 8] = b"SPBTRACE";
const FORMAT: u32 = 1;

/// The tracer's revision, in every key: raise it with any change that alters the tallies traced
/// for the same bench, rays and seed (a sampler, an intersection, a recorder, a tally), so that
/// a cache filled by an earlier build of the same version is never served as this one's trace.
pub const TRACER_REVISION: u32 = 2;

/// A cache key: the hex SHA-256 of what determines a trace.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct CacheKey(String);

impl CacheKey {
    /// The key of tracing `doc` with `rays` rays and `seed`.
    pub fn new(doc: &BenchDoc, rays: u64, seed: u64) -> Result<CacheKey> {
        let mut file = doc.file.clone();
        // The trace reads neither section: leave them out so that editing them keeps the key.
        file.electronics = Default::default();
        file.run = Default::default();
        let mut h = Sha256::new();
        h.update(b"spibench trace cache\n");
        h.update(env!("CARGO_PKG_VERSION").as_bytes());
        h.update([0]);
        h.update(TRACER_REVISION.to_le_bytes());
        h.update(crate::scene::doc::to_ron(&file)?.as_bytes());
        for el in &file.elements {
            if let ElementSpec::Chart(ChartSpec {
                pattern: ChartPatternSpec::Image { path, .. },
                ..
            }) = el
            {
                let full = doc.path().parent().unwrap_or(Path::new(".")).join(path);
                let bytes = std::fs::read(&full).map_err(|e| Error::read(&full, e))?;
                h.update((bytes.len() as u64).to_le_bytes());
                h.update(&bytes);
            }
        }
        h.update(rays.to_le_bytes());
        h.update(seed.to_le_bytes());
        Ok(CacheKey(hex(&h.finalize())))
    }

    pub fn as_str(&self) -> &str {
        &self.0
    }
}

/// What the cache had for a key.
#[derive(Debug, Clone, PartialEq)]
pub enum Lookup {
    Hit(Box<Tallies>),
    Miss,
    /// An entry exists but is damaged (the reason); it will be rebuilt.
    Corrupt(String),
}

/// A folder of cached traces.
#[derive(Debug, Clone)]
pub struct TraceCache {
    dir: PathBuf,
}

impl TraceCache {
    pub fn new(dir: &Path) -> TraceCache {
        TraceCache {
            dir: dir.to_path_buf(),
        }
    }

    pub fn dir(&self) -> &Path {
        &self.dir
    }

    fn entry(&self, key: &CacheKey) -> PathBuf {
        self.dir.join(format!("{}.trace", key.0))
    }

    /// Looks a key up; a damaged entry is reported, never returned.
    pub fn lookup(&self, key: &CacheKey) -> Lookup {
        let path = self.entry(key);
        match std::fs::symlink_metadata(&path) {
            Err(_) => return Lookup::Miss,
            Ok(m) if !m.file_type().is_file() => {
                return Lookup::Corrupt(format!(
                    "{}: not a plain file (a symbolic link or a folder), not opened",
                    path.display()
                ));
            }
            Ok(_) => {}
        }
        let Ok(bytes) = std::fs::read(&path) else {
            return Lookup::Miss;
        };
        match decode_entry(&bytes, key) {
            Ok(t) => Lookup::Hit(Box::new(t)),
            Err(why) => Lookup::Corrupt(format!("{}: {why}", path.display())),
        }
    }

    /// Stores a trace under a key (atomically: a temporary file renamed into place).
    pub fn store(&self, key: &CacheKey, t: &Tallies) -> Result<()> {
        std::fs::create_dir_all(&self.dir).map_err(|e| Error::write(&self.dir, e))?;
        let payload = encode(t);
        let mut out = Vec::with_capacity(payload.len() + 120);
        out.extend_from_slice(MAGIC);
        out.extend_from_slice(&FORMAT.to_le_bytes());
        out.extend_from_slice(key.0.as_bytes());
        out.extend_from_slice(&(payload.len() as u64).to_le_bytes());
        out.extend_from_slice(&Sha256::digest(&payload));
        out.extend_from_slice(&payload);
        let path = self.entry(key);
        let tmp = self
            .dir
            .join(format!(".{}.{}.tmp", key.0, std::process::id()));
        // A fresh file: whatever sits at the temporary name (a link left by anyone) is removed,
        // never written through.
        let _ = std::fs::remove_file(&tmp);
        let written = std::fs::OpenOptions::new()
            .write(true)
            .create_new(true)
            .open(&tmp)
            .and_then(|mut f| std::io::Write::write_all(&mut f, &out));
        written.map_err(|e| Error::write(&tmp, e))?;
        std::fs::rename(&tmp, &path).map_err(|e| {
            let _ = std::fs::remove_file(&tmp);
            Error::write(&path, e)
        })
    }
}

fn decode_entry(bytes: &[u8], key: &CacheKey) -> std::result::Result<Tallies, String> {
    let head = 8 + 4 + 64 + 8 + 32;
    if bytes.len() < head || &bytes[..8] != MAGIC {
        return Err("not a spibench trace-cache entry".into());
    }
    let format = u32::from_le_bytes(bytes[8..12].try_into().map_err(|_| "short header")?);
    if format != FORMAT {
        return Err(format!("cache format {format}, expected {FORMAT}"));
    }
    if &bytes[12..76] != key.0.as_bytes() {
        return Err("the entry holds another key".into());
    }
    let len = u64::from_le_bytes(bytes[76..84].try_into().map_err(|_| "short header")?);
    let payload = &bytes[head..];
    if payload.len() as u64 != len {
        return Err(format!(
            "payload of {} bytes, header says {len}",
            payload.len()
        ));
    }
    if Sha256::digest(payload).as_slice() != &bytes[84..116] {
        return Err("checksum mismatch".into());
    }
    decode(payload).ok_or_else(|| "payload does not decode".into())
}

// ---------------------------------------------------------------------------------------------
// The payload: the merged tallies, field by field, little-endian.

struct Writer(Vec<u8>);

impl Writer {
    fn u64(&mut self, v: u64) {
        self.0.extend_from_slice(&v.to_le_bytes());
    }
    fn f64(&mut self, v: f64) {
        self.0.extend_from_slice(&v.to_le_bytes());
    }
    fn vec(&mut self, v: &[f64]) {
        self.u64(v.len() as u64);
        for &x in v {
            self.f64(x);
        }
    }
}

struct Reader<'a>(&'a [u8]);

impl Reader<'_> {
    fn u64(&mut self) -> Option<u64> {
        let (head, rest) = self.0.split_first_chunk::<8>()?;
        self.0 = rest;
        Some(u64::from_le_bytes(*head))
    }
    fn f64(&mut self) -> Option<f64> {
        self.u64().map(f64::from_bits)
    }
    fn usize(&mut self) -> Option<usize> {
        usize::try_from(self.u64()?).ok()
    }
    fn vec(&mut self) -> Option<Vec<f64>> {
        let n = self.usize()?;
        if n > self.0.len() / 8 {
            return None;
        }
        (0..n).map(|_| self.f64()).collect()
    }
}

fn encode(t: &Tallies) -> Vec<u8> {
    let mut w = Writer(Vec::new());
    for v in [
        t.rays,
        t.arrivals,
        t.seed,
        t.units_across as u64,
        t.units_down as u64,
    ] {
        w.u64(v);
    }
    w.vec(&t.x);
    w.vec(&t.t);
    w.vec(&t.b);
    for l in &t.ledger {
        w.vec(l);
    }
    w.f64(t.outside_cone_w);
    w.u64(t.batches.len() as u64);
    for b in &t.batches {
        w.u64(b.rays);
        let d = b.detected_w;
        for v in [
            b.x, b.g[0], b.g[1], b.c[0], b.c[1], b.b[0], b.b[1], d[0][0], d[0][1], d[1][0], d[1][1],
        ] {
            w.f64(v);
        }
    }
    w.vec(&t.x2);
    for v in t.g2.iter().chain(&t.gx) {
        w.vec(v);
    }
    w.0
}

fn decode(bytes: &[u8]) -> Option<Tallies> {
    let mut r = Reader(bytes);
    let (rays, arrivals, seed) = (r.u64()?, r.u64()?, r.u64()?);
    let (units_across, units_down) = (r.usize()?, r.usize()?);
    let x = r.vec()?;
    let t = r.vec()?;
    let b: [f64; 2] = r.vec()?.try_into().ok()?;
    let ledger = [r.vec()?, r.vec()?, r.vec()?];
    let outside_cone_w = r.f64()?;
    let nb = r.usize()?;
    if nb > bytes.len() / (12 * 8) {
        return None;
    }
    let mut batches = Vec::with_capacity(nb);
    for _ in 0..nb {
        let rays = r.u64()?;
        let mut v = [0.0; 11];
        for x in &mut v {
            *x = r.f64()?;
        }
        batches.push(BatchScalars {
            rays,
            x: v[0],
            g: [v[1], v[2]],
            c: [v[3], v[4]],
            b: [v[5], v[6]],
            detected_w: [[v[7], v[8]], [v[9], v[10]]],
        });
    }
    let x2 = r.vec()?;
    let g2 = [r.vec()?, r.vec()?];
    let gx = [r.vec()?, r.vec()?];
    let units = units_across.checked_mul(units_down)?;
    let consistent = r.0.is_empty()
        && x.len() == units
        && t.len() == 4 * units
        && x2.len() == units
        && g2.iter().chain(&gx).all(|v| v.len() == units);
    consistent.then_some(Tallies {
        rays,
        arrivals,
        seed,
        units_across,
        units_down,
        x,
        t,
        b,
        ledger,
        outside_cone_w,
        batches,
        x2,
        g2,
        gx,
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    fn doc() -> BenchDoc {
        BenchDoc::read(&Path::new(env!("CARGO_MANIFEST_DIR")).join("scenes/paper_bench.ron"))
            .unwrap()
    }

    #[test]
    fn key_follows_the_bench_rays_and_seed_but_not_the_electronics() {
        let d = doc();
        let k = CacheKey::new(&d, 1000, 1).unwrap();
        assert_eq!(k, CacheKey::new(&d, 1000, 1).unwrap());
        assert_ne!(k, CacheKey::new(&d, 1001, 1).unwrap());
        assert_ne!(k, CacheKey::new(&d, 1000, 2).unwrap());
        let mut moved = d.clone();
        moved.set("detectors.minus.decenter_mm.x", 0.1).unwrap();
        assert_ne!(k, CacheKey::new(&moved, 1000, 1).unwrap());
        let mut run = d.clone();
        run.set("run.signal_trace_frames", 3.0).unwrap();
        assert_eq!(k, CacheKey::new(&run, 1000, 1).unwrap());
    }

    #[test]
    fn entries_round_trip_and_damage_is_detected() {
        let d = doc();
        let bench = d.build().unwrap();
        let t = crate::trace::trace(&bench, &crate::trace::TraceOptions::new(3000, 5)).unwrap();
        let dir = std::env::temp_dir().join(format!("spibench-cache-test-{}", std::process::id()));
        let _ = std::fs::remove_dir_all(&dir);
        let cache = TraceCache::new(&dir);
        let key = CacheKey::new(&d, 3000, 5).unwrap();
        assert_eq!(cache.lookup(&key), Lookup::Miss);
        cache.store(&key, &t).unwrap();
        assert_eq!(cache.lookup(&key), Lookup::Hit(Box::new(t.clone())));
        // Flip one byte of the payload: the checksum catches it.
        let path = cache.entry(&key);
        let mut bytes = std::fs::read(&path).unwrap();
        let k = bytes.len() - 9;
        bytes[k] ^= 0x40;
        std::fs::write(&path, &bytes).unwrap();
        assert!(matches!(cache.lookup(&key), Lookup::Corrupt(_)));
        // Truncated: caught too.
        std::fs::write(&path, &bytes[..100]).unwrap();
        assert!(matches!(cache.lookup(&key), Lookup::Corrupt(_)));
        // A link in place of the entry is not followed, even to a good entry elsewhere; the
        // store replaces the link, and the file it pointed to is left as it was.
        #[cfg(unix)]
        {
            let outside = dir.with_extension("outside");
            cache.store(&key, &t).unwrap();
            std::fs::rename(&path, &outside).unwrap();
            std::os::unix::fs::symlink(&outside, &path).unwrap();
            assert!(matches!(cache.lookup(&key), Lookup::Corrupt(w) if w.contains("link")));
            let before = std::fs::read(&outside).unwrap();
            cache.store(&key, &t).unwrap();
            assert!(
                !std::fs::symlink_metadata(&path)
                    .unwrap()
                    .file_type()
                    .is_symlink()
            );
            assert_eq!(std::fs::read(&outside).unwrap(), before);
            assert_eq!(cache.lookup(&key), Lookup::Hit(Box::new(t.clone())));
            let _ = std::fs::remove_file(&outside);
        }
        let _ = std::fs::remove_dir_all(&dir);
    }
}
