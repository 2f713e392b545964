"""Benchmarks run by hand (not tests): figures for the README."""
