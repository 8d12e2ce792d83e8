//! Scene bundle: the versioned contract between `scenegen` (writer) and `simulate` (reader).
//! Needs no GDAL. (Being written; see docs/bundle.md.)
