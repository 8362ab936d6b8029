"""Mutation fuzzing of every decoder and server that takes bytes from outside (docs/fuzzing.md)."""
