"""The reproduction report's blocks as Markdown (``report.md``) and as a standalone HTML page
(``report.html``: figures embedded as base64 PNG, CSS inline, formulas drawn as inline SVG when the
page is written, so it needs no network and no script).

A block is a tuple: ``("h1" | "h2" | "h3", text)``, ``("p", text)``, ``("table", header, rows[,
"verbatim"])`` or ``("figure", name, title, png, what, agree)``; the ASCII formulas of its text
are turned into TeX (:func:`_texify`).
"""

from __future__ import annotations

import base64
import html
import io
import os
import re
from pathlib import Path


# ------------------------------------------------------------------------------------------
# maths: the notes are written with ASCII formulas (F_m, tau, Q^(n-n')); both documents show
# them as maths ($...$ for Markdown renderers, SVG drawn by Matplotlib's mathtext in the HTML page)
# ------------------------------------------------------------------------------------------
_GREEK = {"tau": r"\tau", "eps": r"\varepsilon", "phi": r"\phi", "delta": r"\delta", "sigma": r"\sigma",
          "kappa": r"\kappa", "omega": r"\omega"}
#: Whole ASCII formulas and their TeX (matched before the single symbols).
_FORMULAS = [
    ("(F_m^(n+1)/F_m^n)^(5/6)", r"(F_m^{n+1}/F_m^{n})^{5/6}"),
    ("v_n = Q^(n-n') v_n'", r"v_n = Q^{n-n'} v_{n'}"),
    ("phi_0 (1-q)^(n-n0)", r"\phi_0 (1-q)^{n-n_0}"),
    ("F_m cos^6((t-T)/tau)", r"F_m \cos^6((t-T)/\tau)"),
    ("T(eps; q = 0)", r"T(\varepsilon; q = 0)"),
    ("F_m ~ v^(6/5), times ~ v^(-1/5)", r"F_m \propto v^{6/5}$, times $\propto v^{-1/5}"),
    ("(t - T)/tau", r"(t - T)/\tau"),
    ("|dT|", r"|\Delta T|"),
    ("|dF_m|", r"|\Delta F_m|"),
    ("F/F_m", r"F/F_m"),
    ("Q_F + Q_T", r"Q_F + Q_T"),
    ("Q_T/Q_F", r"Q_T/Q_F"),
    ("F_m,n / F_m,n0", r"F_{m,n} / F_{m,n_0}"),
    ("tau_n / tau_n0", r"\tau_n / \tau_{n_0}"),
    ("F_m^wall / F_m^chain", r"F_m^{wall} / F_m^{chain}"),
    ("tau_wall / tau_chain", r"\tau_{wall} / \tau_{chain}"),
    ("cos^6", r"\cos^6"),
]
_SYMBOL = re.compile(r"(?<![\w$\\])(Q(\d)\^th|[A-Za-z]{1,5}(?:_[A-Za-z0-9']{1,5}|\^\([^)\s]*\)|\^[A-Za-z0-9]+)+"
                     r"|(?:tau|eps|phi|delta|sigma)(?![\w]))(?![\w(])")


def _tex_symbol(token: str) -> str:
    m = re.fullmatch(r"Q(\d)\^th", token)
    if m:
        return f"Q_{m.group(1)}^{{th}}"
    lead = re.match(r"[A-Za-z]+", token)
    head = lead.group(0) if lead else ""  # a token without a letter in front: no symbol to translate
    out = _GREEK.get(head, head)
    for kind, part in re.findall(r"([_^])(\([^)]*\)|[A-Za-z0-9']+)", token[len(head):]):
        part = part.strip("()")
        part = _GREEK.get(part, part)
        out += f"{kind}{{{part}}}" if len(part) > 1 else f"{kind}{part}"
    return out


def _texify(text: str) -> str:
    """ASCII formulas of a note -> TeX between $...$ (text already holding $ is left alone)."""
    if "$" in text:
        return text
    marks: list[str] = []

    def keep(tex: str) -> str:
        marks.append(f"${tex}$")
        return f"\x00{len(marks) - 1}\x00"

    for ascii_, tex in _FORMULAS:
        text = text.replace(ascii_, keep(tex))
    text = re.sub(r"(?<![\w$\\])([A-Za-z]+_[A-Za-z0-9]+|tau|eps)\((\d+)\)",
                  lambda m: keep(f"{_tex_symbol(m.group(1))}({m.group(2)})"), text)
    text = _SYMBOL.sub(lambda m: keep(_tex_symbol(m.group(0))), text)
    return re.sub("\x00(\\d+)\x00", lambda m: marks[int(m.group(1))], text)


# ------------------------------------------------------------------------------------------
# document blocks -> markdown / html
# ------------------------------------------------------------------------------------------
def _md_cell(s: str) -> str:
    return str(s).replace("|", "\\|").replace("\n", " ")


def _to_markdown(blocks: list[tuple], out_dir: Path) -> str:
    lines: list[str] = []
    for b in blocks:
        kind = b[0]
        if kind in ("h1", "h2", "h3"):
            lines += ["#" * int(kind[1]) + " " + b[1], ""]
        elif kind == "p":
            lines += [_texify(b[1]), ""]
        elif kind == "table":
            header, rows = b[1], b[2]
            tex = (lambda x: x) if b[3:] == ("verbatim",) else _texify  # parameter names stay code
            lines.append("| " + " | ".join(_md_cell(tex(h)) for h in header) + " |")
            lines.append("|" + "|".join("---" for _ in header) + "|")
            lines += ["| " + " | ".join(_md_cell(tex(c)) for c in row) + " |" for row in rows]
            lines.append("")
        elif kind == "figure":
            _, name, title, png, what, agree = b
            what, agree = _texify(what), _texify(agree)
            lines += [f"### {title}", ""]
            if png is not None:
                rel = os.path.relpath(png.resolve(), out_dir).replace(os.sep, "/")
                width = _display_width(png)
                size = f' width="{width}"' if width else ""
                lines += [f'<img src="{rel}" alt="{html.escape(title)}"{size}>', ""]
                pdf = png.with_suffix(".pdf")
                if pdf.exists():
                    pdf_rel = os.path.relpath(pdf.resolve(), out_dir).replace(os.sep, "/")
                    lines += [f"Vector version: [{pdf.name}]({pdf_rel})", ""]
            lines += [f"*Shows:* {what}", "", f"*Against the paper:* {agree}", ""]
    return "\n".join(lines).rstrip() + "\n"


_CSS = """
body { font-family: -apple-system, "Segoe UI", Helvetica, Arial, sans-serif; max-width: 60em;
       margin: 2em auto; padding: 0 1em; color: #222; line-height: 1.45; }
h1 { font-size: 1.5em; border-bottom: 2px solid #446; padding-bottom: .2em; }
h2 { font-size: 1.25em; margin-top: 1.8em; border-bottom: 1px solid #ccd; }
h3 { font-size: 1.05em; margin-top: 1.4em; }
table { border-collapse: collapse; margin: .8em 0; font-size: .9em; }
th, td { border: 1px solid #ccd; padding: .25em .6em; text-align: left; vertical-align: top; }
th { background: #eef0f6; }
tr:nth-child(even) td { background: #fafbfd; }
figure { margin: 1em 0 2em 0; }
figure img { max-width: 100%; border: 1px solid #ddd; box-sizing: border-box; }
figcaption { font-size: .92em; margin-top: .4em; }
.missing { color: #a00; }
"""


#: Figures are shown at one scale: a full-width figure (7 in, the paper's two columns) spans
#: the page (_PAGE_PX pixels), a one-column one (3.4 in) half of it.
_FIGURE_DPI, _PX_PER_INCH = 200, 100
_PAGE_PX = 7.0 * _PX_PER_INCH


def _display_width(png: Path) -> int | None:
    """Width [px] to show a figure at, from its PNG size (written at _FIGURE_DPI)."""
    try:
        head = png.read_bytes()[:24]
    except OSError:
        return None
    if head[:8] != b"\x89PNG\r\n\x1a\n":
        return None
    return round(int.from_bytes(head[16:20], "big") / _FIGURE_DPI * _PX_PER_INCH)


#: Formulas drawn by this installation, kept on disk (:func:`_formula_store`): {TeX: HTML}.
_DRAWN: dict[str, str] = {}
#: Whether _DRAWN was read from disk, and whether it holds formulas the file does not.
_STORE = {"read": False, "new": False}
#: Largest formula cache file read [bytes] (the report's ~45 formulas take ~0.3 MB).
_STORE_MAX_BYTES = 16 * 2**20


def _formula_store() -> Path:
    """The file of the formulas this installation has drawn (a report's take ~0.7 CPU-s to draw).

    Beside Numba's cache of the compiled kernels: in ``NUMBA_CACHE_DIR`` when set, else this
    package's ``__pycache__`` (as Numba's own), else the user's cache folder
    (``$XDG_CACHE_HOME/hertzchain`` or ``~/.cache/hertzchain``). The name holds the Matplotlib
    version and a digest of this module, which draws them: either changed, the formulas are drawn
    afresh.
    """
    import hashlib

    import matplotlib

    digest = hashlib.sha256(Path(__file__).read_bytes() + matplotlib.__version__.encode()).hexdigest()[:16]
    name = f"hertzchain-formulas-{digest}.json"
    if os.environ.get("NUMBA_CACHE_DIR"):
        return Path(os.environ["NUMBA_CACHE_DIR"]) / name
    here = Path(__file__).parent / "__pycache__"
    if os.access(here if here.is_dir() else here.parent, os.W_OK):
        return here / name
    return Path(os.environ.get("XDG_CACHE_HOME") or Path.home() / ".cache") / "hertzchain" / name


def _read_formulas() -> None:
    """Fill _DRAWN from :func:`_formula_store` (once; a missing, unreadable or foreign file is skipped)."""
    import json

    _STORE["read"] = True
    try:
        path = _formula_store()
        if not path.is_file() or path.stat().st_size > _STORE_MAX_BYTES:
            return
        stored = json.loads(path.read_text(encoding="utf-8"))
    except (OSError, ValueError):
        return
    if isinstance(stored, dict):
        _DRAWN.update({k: v for k, v in stored.items() if isinstance(k, str) and isinstance(v, str)
                       and v.startswith('<span class="math"') and v.endswith("</svg></span>")})


def _save_formulas() -> None:
    """Write _DRAWN to :func:`_formula_store` when it gained formulas (atomically; a cache that
    cannot be written is left out: the next report draws them again)."""
    import json

    from ..fileio import write_text

    if not _STORE["new"]:
        return
    try:
        path = _formula_store()
        path.parent.mkdir(parents=True, exist_ok=True)
        write_text(path, json.dumps(_DRAWN, sort_keys=True))
        _STORE["new"] = False
    except OSError:
        pass


def _svg_formula(tex: str) -> str:
    """One formula as inline SVG (Matplotlib's mathtext, glyphs as paths: no font, script or
    network needed to show it), lowered to sit on the text's baseline; the TeX is kept in
    ``data-tex`` and as the accessible label. Drawn once per installation (:func:`_formula_store`)."""
    if not _STORE["read"]:
        _read_formulas()
    if tex not in _DRAWN:
        _DRAWN[tex] = _draw_formula(tex)
        _STORE["new"] = True
    return _DRAWN[tex]


def _draw_formula(tex: str) -> str:
    """:func:`_svg_formula`, drawn."""
    from matplotlib import rc_context
    from matplotlib.font_manager import FontProperties
    from matplotlib.mathtext import math_to_image

    buf = io.BytesIO()
    with rc_context({"svg.fonttype": "path", "mathtext.fontset": "dejavusans", "svg.hashsalt": "hertzchain"}):
        depth = math_to_image(f"${tex}$", buf, prop=FontProperties(size=11), format="svg")
    svg = buf.getvalue().decode("utf-8")
    svg = svg[svg.index("<svg"):]
    svg = re.sub(r"<metadata>.*?</metadata>", "", svg, flags=re.S)
    label = html.escape(tex, quote=True)
    svg = svg.replace("<svg ", f'<svg role="img" aria-label="{label}" style="vertical-align: -{depth:.2f}pt" ', 1)
    return f'<span class="math" data-tex="{label}">{svg.strip()}</span>'


def _html_math(text: str) -> str:
    """Escape a note for HTML, its $...$ formulas drawn as inline SVG (:func:`_svg_formula`)."""
    parts = re.split(r"\$([^$]+)\$", _texify(str(text)))
    return "".join(_svg_formula(p) if i % 2 else html.escape(p) for i, p in enumerate(parts))


def _to_html(blocks: list[tuple]) -> str:
    e = html.escape
    m = _html_math
    body: list[str] = []
    title = "hertzchain reproduction"
    for b in blocks:
        kind = b[0]
        if kind in ("h1", "h2", "h3"):
            if kind == "h1":
                title = b[1]
            body.append(f"<{kind}>{e(b[1])}</{kind}>")
        elif kind == "p":
            body.append(f"<p>{m(b[1])}</p>")
        elif kind == "table":
            header, rows = b[1], b[2]
            cell = e if b[3:] == ("verbatim",) else m
            body.append("<table><thead><tr>" + "".join(f"<th>{cell(str(h))}</th>" for h in header)
                        + "</tr></thead><tbody>")
            body += ["<tr>" + "".join(f"<td>{cell(str(c))}</td>" for c in row) + "</tr>" for row in rows]
            body.append("</tbody></table>")
        elif kind == "figure":
            _, name, ftitle, png, what, agree = b
            body.append(f'<h3 id="{e(name)}">{e(ftitle)}</h3><figure>')
            if png is not None and png.is_file():
                data = base64.b64encode(png.read_bytes()).decode("ascii")
                width = _display_width(png)
                size = f' style="width: {100 * width / _PAGE_PX:.1f}%"' if width else ""
                body.append(f'<img alt="{e(ftitle)}" src="data:image/png;base64,{data}"{size}>')
            else:
                body.append(f'<p class="missing">figure file missing: {e(str(png))}</p>')
            body.append(f"<figcaption><b>Shows:</b> {m(what)}<br><b>Against the paper:</b> {m(agree)}"
                        "</figcaption></figure>")
    _save_formulas()
    return ("<!DOCTYPE html>\n<html lang=\"en\"><head><meta charset=\"utf-8\">"
            f"<title>{e(title)}</title><style>{_CSS}</style></head><body>\n"
            + "\n".join(body) + "\n</body></html>\n")
