"""Baselines the paper compares TAX3D with, run on the same demonstrations and rollouts."""
