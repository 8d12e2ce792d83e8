//! Errors of scenegen. Each variant names the file (region, raster, mesh, bundle) and what is
//! wrong; [`ScenegenError::is_bad_input`] separates the user's mistakes (exit code 2) from
//! failures of the machine or of this program (exit code 1).

use std::path::PathBuf;

#[derive(Debug, thiserror::Error)]
pub enum ScenegenError {
    #[error("cannot read region file {}: {source}", path.display())]
    ReadRegion {
        path: PathBuf,
        source: std::io::Error,
    },
    /// Syntax, unknown key, wrong type or value out of range; `key` is the key path.
    #[error("{}: {}{message}", path.display(), if key.is_empty() { String::new() } else { format!("at key `{key}`: ") })]
    Region {
        path: PathBuf,
        key: String,
        message: String,
    },
    /// An input raster or mesh that is missing, unreadable or unusable.
    #[error("{}: {message}", path.display())]
    Input { path: PathBuf, message: String },
    #[error(transparent)]
    Scheme(#[from] landcover::SchemeError),
    #[error(transparent)]
    Tile(#[from] tiles::TileError),
    #[error(transparent)]
    Bundle(#[from] bundle::BundleError),
    /// A GDAL call that failed on something this program made (not a user's file).
    #[error("GDAL: {what}: {source}")]
    Gdal {
        what: String,
        source: gdal::errors::GdalError,
    },
    #[error("{0}")]
    Internal(String),
}

impl ScenegenError {
    /// True for errors caused by the user's input (exit code 2).
    pub fn is_bad_input(&self) -> bool {
        use bundle::BundleError as B;
        match self {
            ScenegenError::ReadRegion { .. }
            | ScenegenError::Region { .. }
            | ScenegenError::Input { .. }
            | ScenegenError::Scheme(_)
            | ScenegenError::Tile(_) => true,
            ScenegenError::Bundle(b) => matches!(
                b,
                B::Exists { .. }
                    | B::NotABundle { .. }
                    | B::Read { .. }
                    | B::Manifest { .. }
                    | B::Version { .. }
                    | B::Corrupt { .. }
                    | B::Brdf { .. }
                    | B::UnknownMaterialIds { .. }
            ),
            ScenegenError::Gdal { .. } | ScenegenError::Internal(_) => false,
        }
    }
}

pub(crate) fn input(path: impl Into<PathBuf>, message: impl Into<String>) -> ScenegenError {
    ScenegenError::Input {
        path: path.into(),
        message: message.into(),
    }
}

pub(crate) fn gdal_err(
    what: impl Into<String>,
) -> impl FnOnce(gdal::errors::GdalError) -> ScenegenError {
    let what = what.into();
    move |source| ScenegenError::Gdal { what, source }
}
