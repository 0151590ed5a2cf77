"""The variant registry's earlier place: it lives in `tax3d.variants`."""

from tax3d.variants import VARIANTS, VariantSpec, variant_spec

__all__ = ["VARIANTS", "VariantSpec", "variant_spec"]
