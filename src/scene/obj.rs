//! Wavefront OBJ/MTL reading (placeholder until the loader lands).
