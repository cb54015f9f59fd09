"""Bad input for `encode` / `sample` / `interpolate`: latents, seeds, temperatures, paths
(builders as in ``vectorize.py``)."""

from __future__ import annotations

import numpy as np

from tests.helpers import TINY, png


def in_latent_nan(d, m):
    np.save(d / "z.npy", np.full(TINY.latent, np.nan, np.float32))
    return ["interpolate", png(d / "a.png"), str(d / "z.npy"), "-o", str(d / "outdir")], None


def in_latent_wrong_size(d, m):
    np.save(d / "z.npy", np.zeros(TINY.latent + 3, np.float32))
    return ["interpolate", png(d / "a.png"), str(d / "z.npy"), "-o", str(d / "outdir")], None


def in_latent_pickle(d, m):
    np.save(d / "z.npy", np.array([{"evil": 1}], dtype=object), allow_pickle=True)
    return ["interpolate", png(d / "a.png"), str(d / "z.npy"), "-o", str(d / "outdir")], None


def in_latent_json_garbage(d, m):
    (d / "z.json").write_text('{"latent": "abc"}\n')
    return ["interpolate", png(d / "a.png"), str(d / "z.json"), "-o", str(d / "outdir")], None


def in_sample_zero(d, m):
    return ["sample", "--n", "0", "-o", str(d / "outdir")], None


def in_temperature_inf(d, m):
    return ["sample", "--temperature", "inf", "-o", str(d / "outdir")], None


def in_seed_beyond_64_bits(d, m):
    return ["vectorize", png(d / "a.png"), "-o", str(d / "out.svg"), "--seed", str(2**70)], None


def in_negative_seed(d, m):
    return ["sample", "--seed", "-1", "-o", str(d / "outdir")], None


def in_interpolate_empty_second(d, m):
    return ["interpolate", png(d / "a.png"), "", "-o", str(d / "outdir")], None


def in_interpolate_onto_its_input(d, m):
    (d / "outdir").mkdir()
    src = png(d / "outdir" / "contact.png")
    return ["interpolate", src, png(d / "b.png"), "-o", str(d / "outdir")], None


def in_interpolate_segments_auto(d, m):
    return ["interpolate", png(d / "a.png"), png(d / "b.png"), "--segments", "auto", "-o", str(d / "outdir")], None


def in_fit_with_a_value(d, m):
    return ["interpolate", png(d / "a.png"), png(d / "b.png"), "--fit=yes", "-o", str(d / "outdir")], None


def in_encode_no_fit_garbage(d, m):
    (d / "a.png").write_bytes(b"not a png")
    return ["encode", str(d / "a.png"), "--no-fit", "-o", str(d / "out.jsonl")], None


def in_latent_npz(d, m):
    """An .npz archive under an .npy name (it was `TypeError: expected np.ndarray (got NpzFile)`)."""
    with open(d / "z.npy", "wb") as f:
        np.savez(f, z=np.zeros(16, np.float32))
    return ["interpolate", png(d / "a.png"), str(d / "z.npy"), "-o", str(d / "outdir")], None


def in_latent_strings(d, m):
    np.save(d / "z.npy", np.array(["a"] * 16))
    return ["interpolate", png(d / "a.png"), str(d / "z.npy"), "-o", str(d / "outdir")], None


def in_latent_complex(d, m):
    """Complex numbers (they were cast to their real parts with a Python warning)."""
    np.save(d / "z.npy", np.ones(16, np.complex64) * 1j)
    return ["interpolate", png(d / "a.png"), str(d / "z.npy"), "-o", str(d / "outdir")], None


def in_temperature_huge(d, m):
    return ["sample", "--temperature", "1e300", "-o", str(d / "outdir")], None
