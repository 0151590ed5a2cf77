"""Training: one loop (loop.py) for TAX3D and DP3, each method's part in a learner (tax3d.py, dp3.py)."""
