"""im2vec: raster images to closed cubic Bezier vector graphics with a learned model.

The Python API (``api.py``) is loaded on first use, so that ``im2vec --help`` does not
import torch::

    import im2vec_cli as iv
    svg = iv.vectorize("glyph.png", iv.load_model("fonts")).to_svg()
"""

__version__ = "0.1.0"

# train, train_aux, train_features and project are in im2vec_cli.api only: the package's modules of those
# names (the training pipelines) would shadow them here
_API = ("load_model", "vectorize", "vectorize_each", "encode", "decode", "sample", "prior_latents", "interpolate", "fit_prior",
        "fit_neighbours", "load_feature_net", "export")
__all__ = ["__version__", "VectorImage", "VectorShape", "VectorizeOptions", *_API]


def __getattr__(name: str):
    if name == "VectorizeOptions":  # torch-free
        from .options import VectorizeOptions

        return VectorizeOptions
    if name in _API:
        from . import api

        return getattr(api, name)
    if name in ("VectorImage", "VectorShape"):
        from . import vector

        return getattr(vector, name)
    raise AttributeError(f"module 'im2vec_cli' has no attribute {name!r}")
