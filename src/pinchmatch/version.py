"""The version of pinchmatch, written into every output document and cache key."""

__version__ = "0.1.0"
