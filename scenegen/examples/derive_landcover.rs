//! Derive a CORINE-coded land-cover raster from a DEM, for examples whose DEM has no matching
//! land-cover sample (the Grenoble DEM and the Lausanne CORINE rasters do not overlap).
//!
//! Usage: `cargo run --release -p scenegen --example derive_landcover -- DEM OUT.tif [CELL_DEG]`
//!
//! The output is EPSG:4326, `CELL_DEG` degrees per pixel (default 0.001°, about 80 m × 110 m at
//! 45° N), covering the DEM; codes are CORINE grid codes chosen by elevation and slope (rules in
//! `classify`), with a "city" disc around Grenoble (5.724° E, 45.188° N). It is a plausible
//! pattern for exercising the pipeline, not a land-cover product.

use gdal::raster::ResampleAlg;
use gdal::Dataset;
use scenegen::synth::write_geotiff;

fn classify(h: f64, slope_deg: f64, lon: f64, lat: f64) -> u8 {
    let city_km = ((lon - 5.724) * 78.7).hypot((lat - 45.188) * 111.2);
    let wobble = ((lon * 900.0).sin() * (lat * 700.0).cos() + 1.0) * 0.5; // 0..1 patches
    if h > 2400.0 {
        31 // bare rock
    } else if h > 2000.0 {
        if slope_deg > 35.0 {
            31
        } else {
            26
        } // natural grassland
    } else if h > 1300.0 {
        if slope_deg > 40.0 {
            31
        } else if wobble > 0.25 {
            24
        } else {
            26
        } // coniferous
    } else if h > 400.0 || slope_deg > 12.0 {
        if wobble > 0.6 {
            25
        } else if wobble > 0.2 {
            23
        } else {
            18
        } // mixed, broad-leaved, pasture
    } else if city_km < 3.0 {
        1 // continuous urban
    } else if city_km < 8.0 {
        if wobble > 0.5 {
            2
        } else {
            12
        }
    } else if wobble > 0.85 {
        41 // water bodies
    } else {
        12 // arable
    }
}

fn main() -> Result<(), Box<dyn std::error::Error>> {
    let args: Vec<String> = std::env::args().collect();
    if args.len() < 3 {
        eprintln!("usage: derive_landcover DEM OUT.tif [CELL_DEG]");
        std::process::exit(2);
    }
    let cell: f64 = args.get(3).map(|s| s.parse()).transpose()?.unwrap_or(0.001);
    let ds = Dataset::open(&args[1])?;
    let gt = ds.geo_transform()?;
    let (w, h) = ds.raster_size();
    let (lon0, lat1) = (gt[0], gt[3]);
    let (lon1, lat0) = (gt[0] + w as f64 * gt[1], gt[3] + h as f64 * gt[5]);
    let ow = ((lon1 - lon0) / cell).floor() as usize;
    let oh = ((lat1 - lat0) / cell).floor() as usize;
    // The DEM resampled bilinearly to the output grid, with one extra pixel for slopes.
    let band = ds.rasterband(1)?;
    let dem = band.read_as::<f32>((0, 0), (w, h), (ow, oh), Some(ResampleAlg::Bilinear))?;
    let d = dem.data();
    let dx = cell * 111_200.0 * (0.5 * (lat0 + lat1)).to_radians().cos();
    let dy = cell * 111_200.0;
    let mut out = vec![0u8; ow * oh];
    for r in 0..oh {
        for c in 0..ow {
            let at = |cc: usize, rr: usize| d[rr.min(oh - 1) * ow + cc.min(ow - 1)] as f64;
            let z = at(c, r);
            let gx = (at(c + 1, r) - at(c.saturating_sub(1), r)) / (2.0 * dx);
            let gy = (at(c, r + 1) - at(c, r.saturating_sub(1))) / (2.0 * dy);
            let slope = gx.hypot(gy).atan().to_degrees();
            let lon = lon0 + (c as f64 + 0.5) * cell;
            let lat = lat1 - (r as f64 + 0.5) * cell;
            out[r * ow + c] = classify(z, slope, lon, lat);
        }
    }
    write_geotiff(
        std::path::Path::new(&args[2]),
        ow,
        oh,
        Some([lon0, cell, 0.0, lat1, 0.0, -cell]),
        Some("EPSG:4326"),
        Some(255.0),
        out,
    )?;
    println!("{}: {ow} × {oh} CORINE codes at {cell}°", args[2]);
    Ok(())
}
