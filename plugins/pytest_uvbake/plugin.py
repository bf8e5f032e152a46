"""pytest plugin for texture-regression images (built in a later issue)."""
