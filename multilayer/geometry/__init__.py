"""The reference meshes, the spaces on them, and the geometry contract (the measure of the meridian plane)."""
