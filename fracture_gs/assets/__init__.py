"""Procedural built-in scenes and interior fill."""
