//! The heavy-tail check (`simulator::heavy_tail`, MCNP's relative variance of the variance):
//! it must flag a deliberately starved run through a water cloud (τ 5, the IPRT A5 Mie phase
//! function with its diffraction peak, 2 000 forward photons, local estimates through the
//! peak), naming the measure and wavelength, and stay silent on well-behaved runs (the DISORT
//! reference cases assert that through `common::run_rows_light_tailed`).

mod common;
use common::*;

fn cloud(spp: u64) -> String {
    format!(
        "seed = 3\n[spectral]\nwavelengths = [800.0]\n[atmosphere]\ntype = \"homogeneous\"\n\
         optical_thickness = 5.0\nsingle_scattering_albedo = 0.999978830724981\n\
         phase = {{ type = \"tabulated\", file = \"fixtures/watercloud.mie.cdf\", wavelength = 800.0 }}\n\
         [surface]\ntype = \"lambertian\"\nreflectance = 0.0\n\
         [illumination]\ntype = \"directional\"\nzenith = 50.0\nazimuth = 0.0\n\
         [integrator]\ntype = \"forward\"\n\
         [[measures]]\nid = \"cloud_top\"\ntype = \"mdistant\"\nconstruct = \"directions\"\n\
         zeniths = [0.0, 30.0, 50.0, 60.0]\nazimuths = [0.0, 180.0, 180.0, 0.0]\nspp = {spp}\n"
    )
}

#[test]
fn starved_cloud_run_is_flagged() {
    let exp = experiment(&cloud(2000));
    let res = simulator::run::run(&exp, false);
    let tails = simulator::heavy_tail::check(&exp, &res);
    assert_eq!(tails.len(), 1, "{tails:?}");
    let msg = tails[0].to_string();
    assert!(
        msg.contains("\"cloud_top\"") && msg.contains("800 nm"),
        "{msg}"
    );
    assert!(tails[0].vov > engine::accum::VOV_LIMIT);
}

#[test]
fn rayleigh_run_is_silent() {
    let text =
        "seed = 3\n[spectral]\nwavelengths = [550.0]\n[atmosphere]\ntype = \"homogeneous\"\n\
                optical_thickness = 0.5\nphase = { type = \"rayleigh\" }\n\
                [surface]\ntype = \"lambertian\"\nreflectance = 0.3\n\
                [illumination]\ntype = \"directional\"\nzenith = 30.0\n\
                [[measures]]\nid = \"pp\"\ntype = \"mdistant\"\nazimuth = 0.0\n\
                zeniths = [-60.0, -30.0, 0.0, 30.0, 60.0]\nspp = 20000\n";
    let exp = experiment(text);
    let res = simulator::run::run(&exp, false);
    assert!(simulator::heavy_tail::check(&exp, &res).is_empty());
}
