"""TAX3D: non-rigid relative placement through 3D dense diffusion, and the HangProcCloth benchmark."""

__version__ = "0.1.0"
