"""Bad input (issue "Hardening"; docs/RELIABILITY.md lists each case): one table of cases, each a
real command on a crafted input with its documented outcome (``bad_input.check_case``). The
inputs are built by ``tests/cli/inputs/``, a module per command."""

from __future__ import annotations

import os
import subprocess
import sys
from pathlib import Path

import pytest

from tests.cli.bad_input import check_case, invoke, table
from tests.cli.inputs import generate, model, render, train, vectorize

# name -> (builder, expected outcome)
CASES = {
    "missing file": (vectorize.in_missing, "error"),
    "zero-byte file": (vectorize.in_zero_bytes, "error"),
    "text file named .png": (vectorize.in_text_named_png, "error"),
    "truncated PNG": (vectorize.in_truncated_png, "error"),
    "corrupt chunk CRC": (vectorize.in_bad_crc, "error"),
    "PNG signature then junk": (vectorize.in_png_signature_then_junk, "error"),
    "corrupt compressed data": (vectorize.in_corrupt_idat, "error"),
    "1x1 image": (vectorize.in_one_pixel, "error"),
    "2x500 sliver": (vectorize.in_sliver, "error"),
    "20000x20000 image": (vectorize.in_20000_square, "error"),
    "picture beyond --max-memory": (vectorize.in_beyond_max_memory, "error"),
    "--max-memory 100M": (vectorize.in_max_memory_too_small, "usage"),
    "decompression bomb (PNG)": (vectorize.in_decompression_bomb, "error"),
    "decompression bomb (GIF screen)": (vectorize.in_gif_bomb, "error"),
    "truncated JPG": (vectorize.in_truncated_jpg, "error"),
    "broken symlink": (vectorize.in_broken_symlink, "error"),
    "folder without images": (vectorize.in_empty_folder, "error"),
    "16-bit grayscale": (vectorize.in_16bit_gray, "ok"),
    "palette with transparency": (vectorize.in_palette_transparency, "ok"),
    "CMYK JPG": (vectorize.in_cmyk_jpg, "ok"),
    "animated GIF": (vectorize.in_animated_gif, "ok"),
    "animated PNG": (vectorize.in_animated_png, "ok"),
    "EXIF-rotated JPG": (vectorize.in_exif_rotated_jpg, "empty"),
    "all-white": (vectorize.in_all_white, "empty"),
    "fully transparent": (vectorize.in_fully_transparent, "empty"),
    "all-black": (vectorize.in_all_black, "ok"),
    "stdin empty": (vectorize.in_stdin_empty, "error"),
    "stdin not an image": (vectorize.in_stdin_junk, "error"),
    "output folder missing": (vectorize.in_output_parent_missing, "error"),
    "--quality nan": (vectorize.in_quality_nan, "usage"),
    "--simplify nan": (vectorize.in_simplify_nan, "usage"),
    "--tolerance nan": (vectorize.in_tolerance_nan, "usage"),
    "--tolerance -1": (vectorize.in_tolerance_negative, "usage"),
    "--tolerance 0": (vectorize.in_tolerance_zero, "usage"),
    "--colors 0": (vectorize.in_colors_zero, "usage"),
    "--colors 1000": (vectorize.in_colors_too_many, "usage"),
    "--max-paths 0": (vectorize.in_max_paths_zero, "usage"),
    "--parts some": (vectorize.in_parts_unknown, "usage"),
    "--preset poster": (vectorize.in_preset_unknown, "usage"),
    "--filter-speckle -1": (vectorize.in_speckle_negative, "usage"),
    "--filter-speckle 100000": (vectorize.in_speckle_huge, "usage"),
    "--filter-speckle 2px": (vectorize.in_speckle_not_a_number, "usage"),
    "--grow -1": (vectorize.in_grow_negative, "usage"),
    "--grow 100000": (vectorize.in_grow_huge, "usage"),
    "--effort sketch": (vectorize.in_effort_unknown, "usage"),
    "--preset pixel on noise": (vectorize.in_preset_pixel_on_a_photo, "ok"),
    "--preset scan on a white page": (vectorize.in_preset_scan_on_white, "empty"),
    "output is the input": (vectorize.in_output_is_the_input, "usage"),
    "output is the input (symlink)": (vectorize.in_output_is_the_input_through_a_link, "usage"),
    "output is the input (hard link)": (vectorize.in_output_is_the_input_hard_link, "usage"),
    "empty input path": (vectorize.in_empty_input_path, "usage"),
    "empty output path": (vectorize.in_empty_output_path, "usage"),
    "stdin over 256 MiB": (vectorize.in_stdin_endless, "error"),
    "unknown option": (vectorize.in_unknown_option, "usage"),
    "--segments 0": (vectorize.in_segments_zero, "usage"),
    "folder to stdout": (vectorize.in_folder_to_stdout, "usage"),
    "output path is a directory": (render.in_output_is_directory, "error"),
    "SVG: not XML": (render.in_render_not_xml, "error"),
    "SVG: relative commands": (render.in_render_relative_commands, "png"),
    "SVG: open path": (render.in_render_open_path, "png"),
    "SVG: font outline (H V Q T S, relative)": (render.in_render_font_outline, "png"),
    "SVG: stroke": (render.in_render_stroke, "png"),
    "SVG: semi-transparent stroke": (render.in_render_semi_transparent_stroke, "error"),
    "SVG: gradient fill": (render.in_render_gradient, "error"),
    "SVG: text": (render.in_render_text, "error"),
    "SVG: coordinates of 1e308": (render.in_render_huge_coordinates, "error"),
    "SVG: 1,000,000 segments": (render.in_render_million_segments, "error"),
    "SVG: viewBox of 100000 x 100000": (render.in_render_huge_viewbox, "error"),
    "SVG: <use> bomb": (render.in_render_use_bomb, "error"),
    "SVG: <use> cycle": (render.in_render_use_cycle, "error"),
    "SVG: 5000 nested groups": (render.in_render_deep_nesting, "error"),
    "render --scale 1000": (render.in_render_scale_1000, "error"),
    "render --scale nan": (render.in_render_scale_nan, "usage"),
    "render --tau nan": (render.in_render_tau_nan, "usage"),
    "render onto its input": (render.in_render_onto_its_input, "usage"),
    "SVG: bad viewBox": (render.in_render_bad_viewbox, "error"),
    "unknown model name": (model.in_unknown_model, "error"),
    "model: missing weights": (model.in_model_missing_weights, "error"),
    "model: truncated weights": (model.in_model_truncated_weights, "error"),
    "model: NaN weights": (model.in_model_nan_weights, "error"),
    "model: config of another version": (model.in_model_config_wrong_version, "error"),
    "model: config not JSON": (model.in_model_config_not_json, "error"),
    "model: config does not match weights": (model.in_model_config_mismatch, "error"),
    "IM2VEC_MODELS missing": (model.in_models_env_missing, "error"),
    "model: config null": (model.in_model_config_null, "error"),
    "model: config out of range": (model.in_model_config_out_of_range, "error"),
    "unknown device": (model.in_unknown_device, "error"),
    "latent with NaN": (generate.in_latent_nan, "error"),
    "latent of the wrong size": (generate.in_latent_wrong_size, "error"),
    "latent .npy holding a pickle": (generate.in_latent_pickle, "error"),
    "latent JSON not numbers": (generate.in_latent_json_garbage, "error"),
    "--temperature inf": (generate.in_temperature_inf, "usage"),
    "seed beyond 64 bits": (generate.in_seed_beyond_64_bits, "usage"),
    "negative seed": (generate.in_negative_seed, "usage"),
    "interpolate with an empty path": (generate.in_interpolate_empty_second, "usage"),
    "interpolate onto its input": (generate.in_interpolate_onto_its_input, "usage"),
    "sample --n 0": (generate.in_sample_zero, "usage"),
    "interpolate --segments auto": (generate.in_interpolate_segments_auto, "usage"),
    "--fit with a value": (generate.in_fit_with_a_value, "usage"),
    "encode --no-fit of a text file named .png": (generate.in_encode_no_fit_garbage, "error"),
    "near-black 16-bit PNG": (vectorize.in_near_black_16bit, "ok"),
    "corrupt EXIF block": (vectorize.in_corrupt_exif, "ok"),
    "output onto a file with a trailing slash": (vectorize.in_output_slash_onto_a_file, "error"),
    "hard-edged clip art (384 px)": (vectorize.in_hard_edged_clip_art, "ok"),
    "model: config asks for huge sizes": (model.in_model_config_huge_sizes, "error"),
    "model: config integer too large for torch": (model.in_model_config_int_too_large, "error"),
    "model: 3 GB sparse config": (model.in_model_config_sparse, "error"),
    "model: config is a FIFO": (model.in_model_config_fifo, "error"),
    "model: int8 weights": (model.in_model_int8_weights, "error"),
    "SVG: nested <svg>": (render.in_render_nested_svg, "error"),
    "SVG: <switch>": (render.in_render_switch, "png"),
    "SVG: <a>": (render.in_render_link, "png"),
    "SVG: <symbol> through <use>": (render.in_render_symbol_through_use, "error"),
    "SVG: definitions outside <defs>": (render.in_render_definitions, "png"),
    "SVG: opacity 50%": (render.in_render_opacity_percent, "error"),
    "latent .npz under an .npy name": (generate.in_latent_npz, "error"),
    "latent of strings": (generate.in_latent_strings, "error"),
    "latent of complex numbers": (generate.in_latent_complex, "error"),
    "sample --temperature 1e300": (generate.in_temperature_huge, "usage"),
    "--max-memory 1e400": (vectorize.in_max_memory_not_finite, "usage"),
    "SVG: entity declarations": (render.in_render_entities, "error"),
    "SVG: gzip bomb": (render.in_render_gzip_bomb, "error"),
    "SVG: gzip-compressed (.svgz)": (render.in_render_svgz, "png"),
    "train config: a binary file": (train.in_config_binary, "error"),
    "train config: 3 GB sparse": (train.in_config_sparse, "error"),
    "train --batch 1000000": (train.in_batch_huge, "error"),
    "train config: null": (train.in_config_null, "error"),
    "train config: a list": (train.in_config_list, "error"),
    "train config: model section not an object": (train.in_config_model_not_object, "error"),
    "train config: segments 0": (train.in_config_segments_zero, "error"),
    "train config: negative lr": (train.in_config_lr_negative, "error"),
    "train config: distillation of an imagevae": (train.in_config_distill_imagevae, "error"),
    "train config: the outline loss for an imagevae": (train.in_config_outline_imagevae, "error"),
}


@pytest.mark.parametrize("name", table(CASES))
def test_bad_input_table(tmp_path, model_dir, name):
    check_case(tmp_path, model_dir, *CASES[name])


def test_reliability_doc_lists_every_case():
    doc = (Path(__file__).resolve().parents[2] / "docs" / "RELIABILITY.md").read_text()
    rows = {line.split("|")[1].strip(): line.split("|")[2].strip() for line in doc.splitlines()
            if line.startswith("| ") and line.count("|") >= 4}
    for name, (_, expect) in CASES.items():
        assert rows.get(name) == expect, name


def test_all_black_is_one_canvas_square(tmp_path, model_dir):
    args, _ = vectorize.in_all_black(tmp_path, model_dir)
    assert invoke(args, None, model_dir).exit_code == 0
    from im2vec_cli.vector import rasterize_svg

    img = rasterize_svg((tmp_path / "out.svg").read_text(), 50, 40)
    assert img.max() < 0.01  # every pixel black, as in the input


def test_no_library_warning_reaches_stderr(tmp_path, model_dir):
    """A corrupt EXIF block, as a real process (pytest's own capture would hide a warning in
    process): Pillow's UserWarnings and their source lines stay off stderr, which is empty."""
    args, _ = vectorize.in_corrupt_exif(tmp_path, model_dir)
    r = subprocess.run([sys.executable, "-m", "im2vec_cli", *args, "--model", model_dir], capture_output=True,
                       text=True, timeout=120)
    assert r.returncode == 0 and r.stderr == "", r.stderr


@pytest.mark.slow  # three real processes under an address-space cap
def test_resource_bounds_under_a_memory_limit(tmp_path):
    """Endless stdin, a huge render and a huge SVG, as real processes limited to 4 GiB of
    address space: each is refused with one error line (before the fixes: 20 GB resident,
    the kernel's OOM killer, and minutes with no output)."""
    import resource

    (tmp_path / "t.svg").write_text('<svg xmlns="http://www.w3.org/2000/svg" viewBox="0 0 64 64">'
                                    '<path d="M 1 1 L 60 1 L 30 60 Z"/></svg>')
    (tmp_path / "big.svg").write_text('<svg xmlns="http://www.w3.org/2000/svg" viewBox="0 0 64 64"><path d="M 1 1 '
                                      + "L 2 2 L 1 1 " * 500_000 + 'Z"/></svg>')
    limit = 4 * 2**30
    cases = [(["vectorize", "-", "-o", str(tmp_path / "out.svg")], "/dev/zero", "more than 256 MiB"),
             (["render", str(tmp_path / "t.svg"), "--scale", "1000", "-o", str(tmp_path / "out.png")], None,
              "megapixels"),
             (["render", str(tmp_path / "big.svg"), "-o", str(tmp_path / "out.png")], None, "segments")]
    for args, stdin, message in cases:
        with open(stdin or os.devnull, "rb") as f:
            r = subprocess.run([sys.executable, "-m", "im2vec_cli", *args], stdin=f, capture_output=True, text=True,
                               timeout=300, preexec_fn=lambda: resource.setrlimit(resource.RLIMIT_AS, (limit, limit)))
        assert r.returncode == 1, (args, r.stderr[-500:])
        assert r.stderr.count("Error:") == 1 and message in r.stderr and "Traceback" not in r.stderr, r.stderr
    assert not list(tmp_path.glob("out*")) and not list(tmp_path.glob(".out*"))


@pytest.mark.parametrize("exc, line", [(RuntimeError("DefaultCPUAllocator: can't allocate memory"),
                                        "Error: out of memory (DefaultCPUAllocator: can't allocate memory)"),
                                       (MemoryError(), "Error: out of memory (MemoryError)"),
                                       (KeyError("x"), "Error: KeyError: 'x'")])
def test_whatever_a_dependency_raises_is_one_line(tmp_path, monkeypatch, exc, line):
    """Nothing ends in a traceback: an error no check foresaw (memory running out in NumPy or
    torch, a dependency's bug) is one `Error:` line, exit 1, no output file."""
    from click.testing import CliRunner

    import im2vec_cli.vector as vector
    from im2vec_cli.cli import cli

    def boom(*a, **k):
        raise exc

    monkeypatch.setattr(vector, "from_svg", boom)
    (tmp_path / "a.svg").write_text('<svg xmlns="http://www.w3.org/2000/svg" width="8" height="8"/>')
    res = CliRunner().invoke(cli, ["render", str(tmp_path / "a.svg"), "-o", str(tmp_path / "a.png")])
    assert res.exit_code == 1 and res.stderr.strip() == line, res.output
    assert not (tmp_path / "a.png").exists()
