"""Bad input for `render`: SVGs that are not ours, bombs, huge canvases and bad options (builders
as in ``vectorize.py``)."""

from __future__ import annotations


def _render(d, svg_text):
    (d / "x.svg").write_text(svg_text)
    return ["render", str(d / "x.svg"), "-o", str(d / "out.png")], None


def _svg(path_d, view_box="0 0 10 10"):
    return f'<svg xmlns="http://www.w3.org/2000/svg" viewBox="{view_box}"><path d="{path_d}"/></svg>'


def in_render_not_xml(d, m):
    return _render(d, "<svg <<<")


def in_render_bad_viewbox(d, m):
    return _render(d, _svg("M 1 1 L 9 1 L 9 9 Z", "0 0 ten 10"))


def in_render_relative_commands(d, m):
    return _render(d, _svg("m 1 1 l 5 0 l 0 5 z"))


def in_render_open_path(d, m):
    return _render(d, _svg("M 1 1 L 9 1 L 9 9"))  # filled as SVG fills it: closed back to the start


def in_render_font_outline(d, m):
    # an ordinary font outline as exported by a font editor: H, V, Q, T, S, relative commands
    return _render(d, _svg("M1 1H9V3h-6v2q2 0 2 2t-2 2s-1 0 -1 -1z"))


def in_render_stroke(d, m):
    return _render(d, _svg('M 1 2 L 8 2 L 8 9" fill="none" stroke="black" stroke-width="2'))  # its filled outline


def in_render_semi_transparent_stroke(d, m):
    return _render(d, _svg('M 1 1 L 9 1 L 9 9 Z" stroke="red" stroke-opacity="0.5'))


def in_render_gradient(d, m):
    return _render(d, '<svg xmlns="http://www.w3.org/2000/svg" viewBox="0 0 10 10"><defs><linearGradient id="g">'
                      '<stop offset="0" stop-color="red"/></linearGradient></defs>'
                      '<path d="M 1 1 L 9 1 L 9 9 Z" fill="url(#g)"/></svg>')


def in_render_text(d, m):
    return _render(d, '<svg xmlns="http://www.w3.org/2000/svg" viewBox="0 0 10 10"><text x="1" y="8">a</text></svg>')


def in_render_huge_coordinates(d, m):
    return _render(d, _svg("M 1e308 1 L 9 1 L 9 9 Z"))


def in_render_million_segments(d, m):
    return _render(d, _svg("M 1 1 " + "L 2 2 L 1 1 " * 500_000 + "Z"))


def in_render_use_bomb(d, m):
    parts = ['<svg xmlns="http://www.w3.org/2000/svg" xmlns:xlink="http://www.w3.org/1999/xlink" viewBox="0 0 10 10">'
             '<defs><path id="g0" d="M1 1 L2 1 L2 2 Z"/>']
    for i in range(1, 8):  # 10^7 paths once expanded
        parts.append(f'<g id="g{i}">' + f'<use xlink:href="#g{i - 1}"/>' * 10 + "</g>")
    return _render(d, "".join(parts) + '</defs><use xlink:href="#g7"/></svg>')


def in_render_use_cycle(d, m):
    return _render(d, '<svg xmlns="http://www.w3.org/2000/svg" xmlns:xlink="http://www.w3.org/1999/xlink" '
                      'viewBox="0 0 10 10"><g id="a"><path d="M1 1 L9 1 L9 9 Z"/><use xlink:href="#a"/></g></svg>')


def in_render_deep_nesting(d, m):
    return _render(d, '<svg xmlns="http://www.w3.org/2000/svg" viewBox="0 0 10 10">' + "<g>" * 5000
                   + '<path d="M1 1 L9 1 L9 9 Z"/>' + "</g>" * 5000 + "</svg>")


def in_render_huge_viewbox(d, m):
    return _render(d, _svg("M 1 1 L 9 1 L 9 9 Z", "0 0 100000 100000"))


def in_render_scale_1000(d, m):
    args, stdin = _render(d, _svg("M 1 1 L 9 1 L 9 9 Z", "0 0 64 64"))
    return args + ["--scale", "1000"], stdin


def in_render_scale_nan(d, m):
    args, stdin = _render(d, _svg("M 1 1 L 9 1 L 9 9 Z"))
    return args + ["--scale", "nan"], stdin


def in_render_tau_nan(d, m):
    args, stdin = _render(d, _svg("M 1 1 L 9 1 L 9 9 Z"))
    return args + ["--tau", "nan"], stdin


def in_render_onto_its_input(d, m):
    (d / "x.svg").write_text(_svg("M 1 1 L 9 1 L 9 9 Z"))
    return ["render", str(d / "x.svg"), "-o", str(d / "x.svg")], None


def in_output_is_directory(d, m):
    (d / "out.png").mkdir()
    return _render(d, _svg("M 1 1 L 9 1 L 9 9 Z"))


_HEAD = '<svg xmlns="http://www.w3.org/2000/svg" width="10" height="10">'


def in_render_nested_svg(d, m):
    return _render(d, _HEAD + '<svg x="5" width="5" height="5" viewBox="0 0 1 1"><rect width="2" height="1"/></svg></svg>')


def in_render_switch(d, m):
    return _render(d, _HEAD + '<switch><rect requiredExtensions="x" width="10" height="10" fill="red"/>'
                   '<rect width="5" height="5"/><rect x="5" width="5" height="5" fill="blue"/></switch></svg>')


def in_render_link(d, m):
    return _render(d, _HEAD + '<a href="https://example.org"><rect width="5" height="5"/></a></svg>')


def in_render_symbol_through_use(d, m):
    return _render(d, _HEAD + '<symbol id="s" viewBox="0 0 1 1"><rect width="1" height="1"/></symbol>'
                   '<use href="#s" width="5" height="5"/></svg>')


def in_render_definitions(d, m):
    return _render(d, _HEAD + '<clipPath id="c"><rect width="10" height="10" fill="red"/></clipPath>'
                   '<marker id="k"><rect width="10" height="10" fill="red"/></marker>'
                   '<symbol id="s"><rect width="10" height="10" fill="red"/></symbol><rect width="5" height="5"/></svg>')


def in_render_opacity_percent(d, m):
    return _render(d, _HEAD + '<rect width="5" height="5" opacity="50%"/></svg>')


def in_render_entities(d, m):
    """Quadratic entity expansion (a 30 MB one took 5.8 GB): entity declarations are refused."""
    return _render(d, '<!DOCTYPE svg [<!ENTITY a "' + "x" * 10000 + '">]>' + _HEAD
                   + "<desc>" + "&a;" * 10000 + '</desc><rect width="5" height="5"/></svg>')


def in_render_gzip_bomb(d, m):
    """An .svgz that inflates past 32 MiB: refused while inflating."""
    import gzip

    body = _HEAD + '<rect width="5" height="5"/><!--' + " " * (40 * 2**20) + "--></svg>"
    (d / "x.svg").write_bytes(gzip.compress(body.encode(), 9))
    return ["render", str(d / "x.svg"), "-o", str(d / "out.png")], None


def in_render_svgz(d, m):
    import gzip

    (d / "x.svg").write_bytes(gzip.compress((_HEAD + '<rect width="5" height="5"/></svg>').encode()))
    return ["render", str(d / "x.svg"), "-o", str(d / "out.png")], None
