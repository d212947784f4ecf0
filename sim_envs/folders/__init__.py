"""Real (or exported) RGB-D folders: layouts, file formats, camera files, depth registration, loading and export."""
