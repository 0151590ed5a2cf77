"""TAX3D: non-rigid relative placement through 3D dense diffusion, and the HangProcCloth benchmark.

    from tax3d import Tax3D
    model = Tax3D.from_pretrained("checkpoints/tax3d-cd-simple")
"""

__version__ = "0.1.0"
__all__ = ["Tax3D"]


def __getattr__(name: str):
    # torch loads on first use of the model, not on `import tax3d` (the command line stays quick to start)
    if name == "Tax3D":
        from tax3d.model.tax3d import Tax3D

        return Tax3D
    raise AttributeError(f"module 'tax3d' has no attribute {name!r}")
