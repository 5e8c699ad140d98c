"""Shared pytest setup: the tests directory is importable (`import corpus`)."""
