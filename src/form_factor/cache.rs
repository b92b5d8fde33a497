//! The form-factor cache (`--cache DIR`): F depends only on the patches' geometry and the
//! estimator's settings, never on ρ or Le, so a run that changes only materials or emission
//! (relighting) can read the F an earlier run stored and go straight to the solve. This module
//! owns the key, the file format and the reading and writing; the pipeline decides when.
//!
//! The key is a 128-bit hash of everything F depends on: the patch mesh (positions,
//! triangles, corner normals, source triangles), the estimator settings that change F, and
//! the format version. Two independent 64-bit lanes of the SplitMix64 finaliser over the
//! words of that description; a collision needs 2⁻¹²⁸ luck. The file `DIR/<key>.ff` holds:
//!
//! ```text
//! "RADIOSITY-FF\n" · version u32 · key [u8; 16] · n u64 · nnz u64 · seconds f64 ·
//! closed_row_tolerance f64 · stats_json_len u64 · stats JSON · indptr [u32; n+1] ·
//! indices [u32; nnz] · data [f32; nnz] · area [f64; n] · visible_fraction [f64; n]
//! ```
//!
//! all little-endian. A file that is missing is a miss; one that is unreadable, truncated or
//! inconsistent is a miss with a warning (and is overwritten). Files are written atomically.

use std::path::{Path, PathBuf};

use serde::Serialize;
use sprs::CsMatI;

use crate::form_factor::{self, FormFactors};
use crate::mesh::Patches;
use crate::sampling::mix64;
use crate::{io, Error, Result};

const MAGIC: &[u8] = b"RADIOSITY-FF\n";
const VERSION: u32 = 1;

/// What the cache did in a run (in the report).
#[derive(Debug, Clone, Default, Serialize)]
pub struct CacheReport {
    /// The cache directory.
    pub dir: String,
    /// Form-factor matrices read from the cache (one per solve: refinement rounds count
    /// separately).
    pub hits: u32,
    /// Form-factor matrices computed and stored.
    pub stored: u32,
    /// Seconds the hits saved: what computing those matrices took when they were stored.
    pub seconds_saved: f64,
}

impl CacheReport {
    /// Nothing done yet with the cache in `dir`.
    pub fn new(dir: &Path) -> CacheReport {
        CacheReport {
            dir: dir.display().to_string(),
            ..CacheReport::default()
        }
    }
}

/// The F stored under `key` in `dir`, counted in `report` (a hit and the seconds it saved);
/// `None` on a miss. A file that exists but cannot be used is a miss with a warning pushed to
/// `warnings` (the F is then computed and the file replaced).
pub fn lookup(
    dir: &Path,
    key: &str,
    n: usize,
    report: &mut CacheReport,
    warnings: &mut Vec<String>,
) -> Option<FormFactors> {
    match load(dir, key, n) {
        Ok(Some((ff, saved))) => {
            report.hits += 1;
            report.seconds_saved += saved;
            Some(ff)
        }
        Ok(None) => None,
        Err(e) => {
            warnings.push(e.to_string());
            None
        }
    }
}

/// The cache key of F for these patches and estimator settings, as 32 hex digits.
pub fn key(patches: &Patches, settings: &form_factor::Settings) -> String {
    let mut h = Hasher::new();
    h.word(VERSION as u64);
    h.word(patches.len() as u64);
    for p in &patches.positions {
        h.vec(*p);
    }
    for i in 0..patches.len() {
        for v in patches.triangles[i] {
            h.word(v as u64);
        }
        for m in patches.corner_normal[i] {
            h.vec(m);
        }
        h.word(patches.source_triangle[i] as u64);
    }
    // Every setting that changes F (the skip of unneeded entries is off with a cache; reuse
    // between refinement rounds keeps F as it was).
    h.word(settings.estimator as u64);
    h.word(settings.samples as u64);
    h.word(settings.rays as u64);
    h.word(settings.seed);
    h.word(settings.reciprocity as u64);
    h.word(settings.shortcuts.skip_hull as u64);
    h.word(settings.shortcuts.normalise_closed as u64);
    h.word(settings.shortcuts.exact_direct as u64);
    h.word(settings.shortcuts.far_field as u64);
    h.hex()
}

/// Two-lane hash over 64-bit words.
struct Hasher([u64; 2]);

impl Hasher {
    fn new() -> Self {
        Hasher([0x243F_6A88_85A3_08D3, 0x1319_8A2E_0370_7344])
    }
    fn word(&mut self, w: u64) {
        self.0[0] = mix64(self.0[0] ^ w);
        self.0[1] = mix64(self.0[1].rotate_left(17) ^ w ^ 0x9E37_79B9_7F4A_7C15);
    }
    fn vec(&mut self, v: glam::DVec3) {
        for x in v.to_array() {
            // +0.0 for −0.0: the same point.
            self.word((x + 0.0).to_bits());
        }
    }
    fn hex(&self) -> String {
        format!("{:016x}{:016x}", self.0[0], self.0[1])
    }
}

/// The file of `key` in `dir`.
pub fn path(dir: &Path, key: &str) -> PathBuf {
    dir.join(format!("{key}.ff"))
}

/// Reads the F stored under `key`: `Ok(None)` if there is none, `Err` (for a warning) if the
/// file exists but cannot be used. On success also returns the seconds it took to compute.
pub fn load(dir: &Path, key: &str, n: usize) -> Result<Option<(FormFactors, f64)>> {
    let file = path(dir, key);
    let bytes = match std::fs::read(&file) {
        Ok(b) => b,
        Err(e) if e.kind() == std::io::ErrorKind::NotFound => return Ok(None),
        Err(e) => return Err(Error::io(&file, e)),
    };
    let bad = |what: &str| Error::Input {
        path: file.clone(),
        message: format!("form-factor cache file is unusable ({what}); it will be recomputed"),
    };
    let mut r = Reader {
        bytes: &bytes,
        at: 0,
    };
    if r.take(MAGIC.len()).ok_or_else(|| bad("truncated"))? != MAGIC {
        return Err(bad("not a cache file"));
    }
    if r.u32().ok_or_else(|| bad("truncated"))? != VERSION {
        return Err(bad("another format version"));
    }
    let stored_key: String = r
        .take(16)
        .ok_or_else(|| bad("truncated"))?
        .iter()
        .map(|b| format!("{b:02x}"))
        .collect();
    if stored_key != key {
        return Err(bad("its key does not match its name"));
    }
    let (rows, nnz) = (
        r.u64().ok_or_else(|| bad("truncated"))? as usize,
        r.u64().ok_or_else(|| bad("truncated"))? as usize,
    );
    if rows != n || nnz > u32::MAX as usize || bytes.len() < nnz * 8 {
        return Err(bad("sizes do not match the patches"));
    }
    let seconds = r.f64().ok_or_else(|| bad("truncated"))?;
    let closed_row_tolerance = r.f64().ok_or_else(|| bad("truncated"))?;
    let json_len = r.u64().ok_or_else(|| bad("truncated"))? as usize;
    let stats: form_factor::Stats =
        serde_json::from_slice(r.take(json_len).ok_or_else(|| bad("truncated"))?)
            .map_err(|_| bad("bad counters"))?;
    let indptr: Vec<u32> = (0..=n)
        .map(|_| r.u32())
        .collect::<Option<_>>()
        .ok_or_else(|| bad("truncated"))?;
    let indices: Vec<u32> = (0..nnz)
        .map(|_| r.u32())
        .collect::<Option<_>>()
        .ok_or_else(|| bad("truncated"))?;
    let data: Vec<f32> = (0..nnz)
        .map(|_| r.f32())
        .collect::<Option<_>>()
        .ok_or_else(|| bad("truncated"))?;
    let area: Vec<f64> = (0..n)
        .map(|_| r.f64())
        .collect::<Option<_>>()
        .ok_or_else(|| bad("truncated"))?;
    let visible_fraction: Vec<f64> = (0..n)
        .map(|_| r.f64())
        .collect::<Option<_>>()
        .ok_or_else(|| bad("truncated"))?;
    if r.at != bytes.len() {
        return Err(bad("trailing bytes"));
    }
    let matrix =
        CsMatI::try_new((n, n), indptr, indices, data).map_err(|_| bad("not a CSR matrix"))?;
    let ff = FormFactors {
        matrix,
        pair_matrix: None,
        stats,
        area,
        visible_fraction,
        closed_row_tolerance,
    };
    ff.validate(0.1).map_err(|_| bad("invalid form factors"))?;
    Ok(Some((ff, seconds)))
}

/// Stores `ff` under `key` (atomically), with the seconds it took to compute.
pub fn store(dir: &Path, key: &str, ff: &FormFactors, seconds: f64) -> Result<()> {
    std::fs::create_dir_all(dir).map_err(|e| Error::io(dir, e))?;
    let m = &ff.matrix;
    let stats = serde_json::to_vec(&ff.stats)
        .map_err(|e| Error::Internal(format!("cache counters: {e}")))?;
    let mut out = Vec::with_capacity(64 + stats.len() + m.nnz() * 8 + ff.len() * 20);
    out.extend_from_slice(MAGIC);
    out.extend_from_slice(&VERSION.to_le_bytes());
    for k in 0..16 {
        out.push(u8::from_str_radix(&key[2 * k..2 * k + 2], 16).expect("hex key"));
    }
    out.extend_from_slice(&(ff.len() as u64).to_le_bytes());
    out.extend_from_slice(&(m.nnz() as u64).to_le_bytes());
    out.extend_from_slice(&seconds.to_le_bytes());
    out.extend_from_slice(&ff.closed_row_tolerance.to_le_bytes());
    out.extend_from_slice(&(stats.len() as u64).to_le_bytes());
    out.extend_from_slice(&stats);
    for &p in m.indptr().raw_storage() {
        out.extend_from_slice(&p.to_le_bytes());
    }
    for &j in m.indices() {
        out.extend_from_slice(&j.to_le_bytes());
    }
    for &f in m.data() {
        out.extend_from_slice(&f.to_le_bytes());
    }
    for &a in &ff.area {
        out.extend_from_slice(&a.to_le_bytes());
    }
    for &v in &ff.visible_fraction {
        out.extend_from_slice(&v.to_le_bytes());
    }
    io::write_atomic(&path(dir, key), &out)
}

/// Little-endian reader over a byte slice.
struct Reader<'a> {
    bytes: &'a [u8],
    at: usize,
}

impl<'a> Reader<'a> {
    fn take(&mut self, k: usize) -> Option<&'a [u8]> {
        let s = self.bytes.get(self.at..self.at.checked_add(k)?)?;
        self.at += k;
        Some(s)
    }
    fn u32(&mut self) -> Option<u32> {
        Some(u32::from_le_bytes(self.take(4)?.try_into().ok()?))
    }
    fn u64(&mut self) -> Option<u64> {
        Some(u64::from_le_bytes(self.take(8)?.try_into().ok()?))
    }
    fn f32(&mut self) -> Option<f32> {
        Some(f32::from_le_bytes(self.take(4)?.try_into().ok()?))
    }
    fn f64(&mut self) -> Option<f64> {
        Some(f64::from_le_bytes(self.take(8)?.try_into().ok()?))
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::mesh::{subdivide, DEFAULT_CREASE_DEGREES};
    use crate::validation::scenes;

    #[test]
    fn the_key_follows_geometry_and_estimator_not_materials() {
        let scene = scenes::furnace_room(0.5, 1.0).unwrap();
        let p = subdivide(&scene, 0.5, DEFAULT_CREASE_DEGREES).unwrap();
        let s = form_factor::Settings::default();
        let k = key(&p, &s);
        assert_eq!(k.len(), 32);
        let mut relit = p.clone();
        relit.reflectance[0] = [0.1; 3];
        relit.emission[3] = [9.0; 3];
        assert_eq!(key(&relit, &s), k, "materials do not change F");
        let mut moved = p.clone();
        moved.positions[0].x += 1e-9;
        assert_ne!(key(&moved, &s), k);
        for other in [
            form_factor::Settings { samples: 6, ..s },
            form_factor::Settings { seed: 2, ..s },
            form_factor::Settings {
                estimator: form_factor::Estimator::Hemisphere,
                ..s
            },
        ] {
            assert_ne!(key(&p, &other), k);
        }
    }

    #[test]
    fn store_and_load_round_trip() {
        let scene = scenes::furnace_room(0.5, 1.0).unwrap();
        let p = subdivide(&scene, 0.5, DEFAULT_CREASE_DEGREES).unwrap();
        let corners: Vec<_> = (0..p.len()).map(|i| p.corners(i)).collect();
        let vis = crate::visibility::Visibility::build(&corners);
        let s = form_factor::Settings::default();
        let ff = form_factor::compute(&p, &vis, &s, &form_factor::Needed::all(p.len())).unwrap();
        let dir = std::env::temp_dir().join(format!("radiosity-cache-{}", std::process::id()));
        let k = key(&p, &s);
        assert!(load(&dir, &k, p.len()).unwrap().is_none());
        store(&dir, &k, &ff, 1.5).unwrap();
        let (back, seconds) = load(&dir, &k, p.len()).unwrap().unwrap();
        assert_eq!(seconds, 1.5);
        assert_eq!(back.matrix, ff.matrix);
        assert_eq!(back.area, ff.area);
        assert_eq!(back.visible_fraction, ff.visible_fraction);
        assert_eq!(back.stats.nnz, ff.stats.nnz);
        // Another patch count: refused.
        assert!(load(&dir, &k, p.len() + 1).is_err());
        let _ = std::fs::remove_dir_all(dir);
    }
}
