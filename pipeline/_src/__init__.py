"""Internals of the batch runner; the public surface is ``pipeline`` itself."""
