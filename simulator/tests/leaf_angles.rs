//! Leaf inclinations of the generated cone trees (RAMI HET06) against the Goel–Strebel
//! distribution and against an independently generated leaf cloud.
//!
//! Goel & Strebel (1984) leaf inclination, as in RAMI-IV and Eradiate: with x = 2θ/π (θ the
//! angle of the leaf normal from the vertical), f(x) ∝ (1 − x)^(μ−1) · x^(ν−1), i.e.
//! x ~ Beta(ν, μ): mean ν/(μ+ν), E[x²] = ν(ν+1)/((μ+ν)(μ+ν+1)).
//!
//! Reference: `../shared/data/canopy/hom/hom_leaves.txt` (9549 leaves made by another generator
//! with μ = 1.066, ν = 1.853; `canopy/MANIFEST.md`): its mean x is 0.6395 (Beta(ν, μ): 0.6348;
//! the swapped Beta(μ, ν): 0.3652). Both orders have the same variance, so the test compares the
//! mean and the raw second moment E[x²], which tell them apart.
//!
//! Statistical test: for each moment, z = (a − b) / √(se_a² + se_b² + floor²), the standard errors
//! from the sample variances of x (resp. x²) and the floor 1e-3 for the f32 normals and the
//! file's nine printed digits; |z| < 4 is required. Needs the shared data folder (`../shared/data`
//! beside the repository, or `SIMULATOR_SHARED_DATA`) for the file comparison; the comparison with
//! the closed-form moments runs without it.

use std::path::{Path, PathBuf};

use engine::bundle::*;
use engine::scene::build::ConeTrees;
use glam::DVec3;

const MU: f64 = 1.066;
const NU: f64 = 1.853;
const FLOOR: f64 = 1e-3;
const Z_MAX: f64 = 4.0;

fn shared() -> Option<PathBuf> {
    let p = std::env::var_os("SIMULATOR_SHARED_DATA")
        .map(PathBuf::from)
        .unwrap_or_else(|| Path::new(env!("CARGO_MANIFEST_DIR")).join("../../shared/data"));
    p.join("canopy/hom/hom_leaves.txt").is_file().then_some(p)
}

/// x = 2θ/π of a leaf normal (either face: θ in [0, π/2]).
fn x_of(nz: f64, norm: f64) -> f64 {
    (nz.abs() / norm).min(1.0).acos() / std::f64::consts::FRAC_PI_2
}

/// Sample moments of x and x²: (mean, its standard error) for each.
struct Moments {
    n: usize,
    m1: (f64, f64),
    m2: (f64, f64),
}

fn moments(xs: &[f64]) -> Moments {
    let n = xs.len() as f64;
    let mean_se = |v: &mut dyn Iterator<Item = f64>| {
        let v: Vec<f64> = v.collect();
        let m = v.iter().sum::<f64>() / n;
        let var = v.iter().map(|a| (a - m).powi(2)).sum::<f64>() / (n - 1.0);
        (m, (var / n).sqrt())
    };
    Moments {
        n: xs.len(),
        m1: mean_se(&mut xs.iter().copied()),
        m2: mean_se(&mut xs.iter().map(|x| x * x)),
    }
}

fn z(a: (f64, f64), b: (f64, f64)) -> f64 {
    (a.0 - b.0) / (a.1 * a.1 + b.1 * b.1 + FLOOR * FLOOR).sqrt()
}

fn generated() -> Vec<f64> {
    let trees = ConeTrees {
        positions: vec![DVec3::ZERO],
        trunk_radius: 0.15,
        trunk_bottom: -0.1,
        trunk_top: 1.5,
        trunk_brdf: BrdfSpec::Lambertian(LambertianSpec {
            reflectance: Spectrum::Constant(0.14),
        }),
        crown_height: 12.0,
        crown_radius: 1.8,
        leaves: 50_000,
        leaf_radius: 0.05,
        mu: MU,
        nu: NU,
        leaf_brdf: BrdfSpec::BiLambertian(BiLambertianSpec {
            reflectance: Spectrum::Constant(0.08),
            transmittance: Spectrum::Constant(0.03),
        }),
        variants: 4,
        seed: 6,
    };
    (0..trees.variants)
        .flat_map(|k| trees.crown(k))
        .map(|d| {
            let n = DVec3::from_array(d.normal.map(f64::from));
            x_of(n.z, n.length())
        })
        .collect()
}

#[test]
fn cone_tree_leaf_inclinations_follow_goel_strebel() {
    let gen = moments(&generated());
    let (a, b) = (NU, MU); // x ~ Beta(ν, μ)
    let mean = a / (a + b);
    let second = a * (a + 1.0) / ((a + b) * (a + b + 1.0));
    let z1 = z(gen.m1, (mean, 0.0));
    let z2 = z(gen.m2, (second, 0.0));
    eprintln!(
        "generated n = {}: E[x] = {:.5} ± {:.5} (Beta(ν, μ) {mean:.5}, z = {z1:.2}), \
         E[x²] = {:.5} ± {:.5} (Beta(ν, μ) {second:.5}, z = {z2:.2})",
        gen.n, gen.m1.0, gen.m1.1, gen.m2.0, gen.m2.1
    );
    assert!(z1.abs() < Z_MAX && z2.abs() < Z_MAX, "z = {z1:.2}, {z2:.2}");
}

#[test]
fn cone_tree_leaf_inclinations_match_hom_leaves() {
    let Some(shared) = shared() else {
        eprintln!("skipping: shared/data/canopy/hom/hom_leaves.txt not found");
        return;
    };
    let path = shared.join("canopy/hom/hom_leaves.txt");
    let text = std::fs::read_to_string(&path).unwrap();
    let header = text.lines().find(|l| l.contains("mu=")).unwrap();
    assert!(
        header.contains("mu=1.066 nu=1.853"),
        "{}: generator settings changed: {header}",
        path.display()
    );
    let xs: Vec<f64> = text
        .lines()
        .filter(|l| !l.starts_with('#') && !l.trim().is_empty())
        .map(|l| {
            let v: Vec<f64> = l.split_whitespace().map(|s| s.parse().unwrap()).collect();
            x_of(v[5], DVec3::new(v[3], v[4], v[5]).length())
        })
        .collect();
    assert_eq!(xs.len(), 9549);
    let file = moments(&xs);
    let gen = moments(&generated());
    let z1 = z(gen.m1, file.m1);
    let z2 = z(gen.m2, file.m2);
    eprintln!(
        "file n = {}: E[x] = {:.5} ± {:.5}, E[x²] = {:.5} ± {:.5}; generated n = {}: \
         E[x] = {:.5} ± {:.5}, E[x²] = {:.5} ± {:.5}; z = {z1:.2}, {z2:.2}",
        file.n,
        file.m1.0,
        file.m1.1,
        file.m2.0,
        file.m2.1,
        gen.n,
        gen.m1.0,
        gen.m1.1,
        gen.m2.0,
        gen.m2.1
    );
    assert!(z1.abs() < Z_MAX && z2.abs() < Z_MAX, "z = {z1:.2}, {z2:.2}");
}
