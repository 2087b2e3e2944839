//! Spherical triangles and polygons (to be written).
