"""Building blocks of the self-contained HTML reports (``reachwise.report``).

A report is one HTML file: CSS inline, figures embedded as base64 PNG ``data:`` URIs,
no external URL, no JavaScript. Every string that may come from user input (robot,
task and scenario names, file names, notes) goes through :func:`esc`; the helpers
here escape every cell and caption unless it is wrapped in :class:`Raw` (markup this
module built itself).
"""

from __future__ import annotations

import base64
import html
import io
import math
from collections.abc import Iterable, Mapping, Sequence
from datetime import UTC, datetime
from pathlib import Path
from string import Template
from typing import TYPE_CHECKING, Any

from reachwise._version import __version__
from reachwise.io.atomic import atomic_write

if TYPE_CHECKING:
    from matplotlib.figure import Figure

PNG_SIGNATURE = b"\x89PNG\r\n\x1a\n"

CSS = """
body{font:15px/1.45 system-ui,-apple-system,"Segoe UI",Roboto,sans-serif;margin:0;
color:#1b1f24;background:#f6f7f9}
header{background:#1f3a5f;color:#fff;padding:18px 32px}
header h1{margin:0;font-size:24px}header p{margin:4px 0 0;opacity:.85}
main{max-width:1180px;margin:0 auto;padding:8px 32px 40px}
section{background:#fff;border:1px solid #dde1e6;border-radius:6px;margin:18px 0;
padding:6px 20px 14px}
h2{font-size:19px;border-bottom:1px solid #e3e6ea;padding-bottom:4px}
h3{font-size:16px;margin-bottom:4px}
table{border-collapse:collapse;margin:8px 0 4px;font-size:13.5px}
caption{caption-side:bottom;text-align:left;font-size:12.5px;color:#57606a;
padding-top:4px;max-width:1000px}
th,td{border:1px solid #d0d7de;padding:3px 9px;text-align:right;vertical-align:top}
th{background:#eef1f4}td.l,th.l{text-align:left}td:not(.l){white-space:nowrap}
tr.bad td{background:#fdecec}tr.good td{background:#eaf6ec}
figure{margin:12px 0}figure img{max-width:100%;height:auto;border:1px solid #e3e6ea}
figcaption{font-size:12.5px;color:#57606a;max-width:1000px}
dl.kv{display:grid;grid-template-columns:max-content auto;gap:2px 16px;margin:8px 0}
dl.kv dt{color:#57606a}dl.kv dd{margin:0}
.ok{color:#1a7f37;font-weight:600}.no{color:#cf222e;font-weight:600}
.note{font-size:13px;color:#57606a}
code{background:#eef1f4;padding:0 3px;border-radius:3px}
details summary{cursor:pointer;color:#1f3a5f;margin:6px 0}
footer{text-align:center;color:#8c959f;font-size:12px;padding:0 0 24px}
"""

_PAGE = Template(
    """<!DOCTYPE html>
<html lang="en">
<head>
<meta charset="utf-8">
<meta name="viewport" content="width=device-width, initial-scale=1">
<title>$title</title>
<link rel="icon" href="data:,">
<style>$css</style>
</head>
<body>
<header><h1>$title</h1><p>$subtitle</p></header>
<main>
$body
</main>
<footer>written by reachwise $version on $date</footer>
</body>
</html>
"""
)


class Raw(str):
    """Markup built by these helpers: inserted as is, never escaped again."""


def esc(value: object) -> str:
    """HTML-escape anything (quotes included); :class:`Raw` passes through."""
    if isinstance(value, Raw):
        return str(value)
    return html.escape(str(value), quote=True)


def num(value: Any, digits: int = 4, unit: str = "") -> str:
    """A number for a table: fixed ``digits`` decimals, ``–`` for None/NaN."""
    if value is None:
        return "–"
    if isinstance(value, bool):
        return "yes" if value else "no"
    if isinstance(value, int):
        return f"{value}{unit}"
    v = float(value)
    if math.isnan(v):
        return "–"
    if math.isinf(v):
        return ("∞" if v > 0 else "−∞") + unit
    return f"{v:.{digits}f}{unit}"


def yes_no(ok: bool) -> Raw:
    return Raw('<span class="ok">yes</span>' if ok else '<span class="no">no</span>')


def table(
    head: Sequence[object],
    rows: Iterable[Sequence[object]],
    *,
    caption: object = None,
    id: str | None = None,
    left: Sequence[int] = (0,),
    row_class: Sequence[str] | None = None,
) -> Raw:
    """A table; columns ``left`` are left-aligned; every cell is escaped (see Raw)."""
    ix = f' id="{esc(id)}"' if id else ""

    def cell(tag: str, j: int, v: object) -> str:
        cls = ' class="l"' if j in left else ""
        return f"<{tag}{cls}>{esc(v)}</{tag}>"

    out = [f"<table{ix}>"]
    if caption is not None:
        out.append(f"<caption>{esc(caption)}</caption>")
    out.append("<thead><tr>" + "".join(cell("th", j, h) for j, h in enumerate(head)) + "</tr>")
    out.append("</thead><tbody>")
    for i, r in enumerate(rows):
        cls = f' class="{esc(row_class[i])}"' if row_class and row_class[i] else ""
        out.append(f"<tr{cls}>" + "".join(cell("td", j, v) for j, v in enumerate(r)) + "</tr>")
    out.append("</tbody></table>")
    return Raw("".join(out))


def key_values(items: Mapping[str, object]) -> Raw:
    """A definition list of ``name: value`` lines."""
    body = "".join(f"<dt>{esc(k)}</dt><dd>{esc(v)}</dd>" for k, v in items.items())
    return Raw(f'<dl class="kv">{body}</dl>')


def section(title: object, *parts: object, id: str | None = None) -> Raw:
    """``<section>`` with an ``<h2>`` and the parts (strings are escaped paragraphs)."""
    ix = f' id="{esc(id)}"' if id else ""
    inner = "".join(p if isinstance(p, Raw) else f"<p>{esc(p)}</p>" for p in parts)
    return Raw(f"<section{ix}><h2>{esc(title)}</h2>{inner}</section>")


def para(text: object, cls: str | None = None) -> Raw:
    c = f' class="{esc(cls)}"' if cls else ""
    return Raw(f"<p{c}>{esc(text)}</p>")


def details(summary: object, body: Raw) -> Raw:
    """A collapsed block (``<details>``, no script needed)."""
    return Raw(f"<details><summary>{esc(summary)}</summary>{body}</details>")


def link(href: str, text: object) -> Raw:
    """A relative link (the reports never link outside the results folder)."""
    return Raw(f'<a href="{esc(href)}">{esc(text)}</a>')


# ---- figures ------------------------------------------------------------------------------
def png_bytes(fig: Figure, dpi: int = 100) -> bytes:
    """A matplotlib figure rendered to PNG bytes (Agg backend)."""
    buf = io.BytesIO()
    fig.savefig(buf, format="png", dpi=dpi)
    return buf.getvalue()


def png_of(source: Figure | bytes | str | Path, dpi: int = 100) -> bytes:
    """PNG bytes of a figure, of bytes (checked), or of a PNG file."""
    if isinstance(source, bytes):
        data = source
    elif isinstance(source, str | Path):
        data = Path(source).read_bytes()
    else:
        data = png_bytes(source, dpi)
    if not data.startswith(PNG_SIGNATURE):
        from reachwise.errors import InputError

        raise InputError(str(source)[:80], "figure", "not a PNG image")
    return data


def data_uri(png: bytes) -> str:
    return "data:image/png;base64," + base64.b64encode(png).decode("ascii")


def figure(source: Figure | bytes | str | Path, caption: object, alt: object = "") -> Raw:
    """An embedded PNG figure with its caption."""
    uri = data_uri(png_of(source))
    return Raw(
        f'<figure><img src="{uri}" alt="{esc(alt or caption)}">'
        f"<figcaption>{esc(caption)}</figcaption></figure>"
    )


def page(title: object, subtitle: object, body: Iterable[Raw | str]) -> str:
    """The whole HTML document."""
    return _PAGE.substitute(
        title=esc(title),
        subtitle=esc(subtitle),
        css=CSS,
        body="\n".join(b if isinstance(b, Raw) else str(para(b)) for b in body),
        version=esc(__version__),
        date=datetime.now(UTC).strftime("%Y-%m-%d %H:%M UTC"),
    )


def write_page(path: str | Path, text: str) -> Path:
    """Write the report atomically (a reader never sees half a file)."""
    out = Path(path)
    out.parent.mkdir(parents=True, exist_ok=True)
    return atomic_write(out, text)


def comparison(rows: Sequence[tuple[object, object, object, object]], id: str) -> Raw:
    """The "thesis says / we measured" table: (quantity, thesis, ours, note) rows."""
    return table(
        ("quantity", "thesis says", "we measured", "note"),
        rows,
        id=id,
        left=(0, 1, 2, 3),
    )
