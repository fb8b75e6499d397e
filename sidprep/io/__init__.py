"""File formats, one module per format, each a read/write pair with a version."""
