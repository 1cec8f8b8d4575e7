"""Accuracy against cost, stability of hard cases, benchmarks, peers."""
