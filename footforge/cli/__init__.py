"""Command lines, thin over the library: `footforge` (main) and the training pipelines (train)."""
