//! Conventional cross-correlation PIV on image pairs and on frames rebuilt from events.
