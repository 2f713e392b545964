"""Seed 002's own cases: critical lengths, equal lengths, adjacent equal lengths, one cable, and its traversal solver."""
