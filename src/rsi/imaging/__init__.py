"""Seed §2.1-2.3: camera model, ambient-light compensation and image registration."""
