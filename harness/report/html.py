"""HTML, written once: the page shell and the table are jinja2 templates (harness/report/templates/)
with autoescape on, so that every value is escaped unless it is already markup (markupsafe.Markup).
The helpers below return markup: a number formatted, a value in code type, a verdict coloured, a
figure, a section. A renderer composes them; any text it takes from results.json passes through
`esc` or a template, never into HTML as it is."""

from __future__ import annotations

from collections.abc import Iterable, Sequence

from jinja2 import Environment, PackageLoader
from markupsafe import Markup, escape

_ENV = Environment(loader=PackageLoader("harness.report", "templates"), autoescape=True,
                   trim_blocks=True, lstrip_blocks=True, keep_trailing_newline=True)

LONG_CELL = 40  # characters: a cell longer than this wraps (td.text); the table scrolls inside its own box
DASH = Markup("\u2013")  # a value that is not there: the character itself, the same escaped or not

STYLE = """
body { font-family: system-ui, sans-serif; max-width: 60rem; margin: 1rem auto; padding: 0 1rem; color: #222; }
body.wide { max-width: none; }
h1 { font-size: 1.5rem; } h2 { border-bottom: 1px solid #ccc; margin-top: 2rem; } h3 { font-size: 1rem; }
table { border-collapse: collapse; font-size: 0.8rem; margin: 0.5rem 0; }
th, td { border: 1px solid #ddd; padding: 0.15rem 0.4rem; text-align: right; vertical-align: top; }
th { background: #f4f4f4; } td:first-child, th:first-child { text-align: left; }
td { white-space: nowrap; } table.wrap td, td:first-child, td small, td.text { white-space: normal; }
td.text { min-width: 12rem; text-align: left; } div.table { overflow-x: auto; max-width: 100%; }
td code { font-size: 0.7rem; }
.verdict { font-size: 2rem; font-weight: bold; padding: 0.4rem 1rem; display: inline-block; border-radius: 0.3rem; }
.pass { background: #d8f5d8; color: #145214; } .fail { background: #fbd9d9; color: #7a1010; }
.ok { color: #145214; } .bad { color: #9b1111; font-weight: bold; } .warn { color: #7a4b00; }
figure { margin: 0.8rem 0; } figure svg { max-width: 100%; height: auto; }
figcaption { font-size: 0.8rem; color: #555; }
pre { background: #f7f7f7; padding: 0.5rem; font-size: 0.75rem; overflow-x: auto; }
nav a { margin-right: 0.8rem; font-size: 0.85rem; }
"""


def esc(x) -> Markup:
    """Any value as text in HTML."""
    return escape(str(x))


def num(x, digits: int = 3) -> Markup:
    """A number as the report writes it: `digits` + 3 significant digits between 1e-3 and 1e6,
    else `digits` after the point in exponent form; None as a dash, a bool as yes or no."""
    if x is None:
        return DASH
    if isinstance(x, bool):
        return Markup("yes" if x else "no")
    if isinstance(x, int):
        return Markup(str(x))
    x = float(x)
    if x == 0.0:
        return Markup("0")
    if 1e-3 <= abs(x) < 1e6:
        return Markup(f"{x:.{digits + 3}g}")
    return Markup(f"{x:.{digits}e}")


def code(x) -> Markup:
    """A value in code type: a file, a metric, a plugin."""
    return Markup("<code>{}</code>").format(x)


def mark(good: bool, text) -> Markup:
    """`text` coloured as a good (ok) or a bad (bad) outcome."""
    return Markup('<span class="{}">{}</span>').format("ok" if good else "bad", text)


def table(header: Sequence[str], rows: Iterable[Sequence], cls: str = "") -> str:
    """Every header and cell escaped, but for cells that are markup already (`esc`, `num`, `code`,
    `mark`). The HTML it returns, like `figure`'s and `section`'s, is plain text for the renderer
    to compose (Markup + str would escape the str)."""
    return _ENV.get_template("table.html").render(header=header, rows=rows, cls=cls, long=LONG_CELL)


def figure(svg: str, caption: str) -> str:
    """An inline SVG figure (harness/report/plots.py writes it) with its caption."""
    return str(Markup("<figure>{}<figcaption>{}</figcaption></figure>").format(Markup(svg), caption))


def section(anchor: str, title: str, body: str) -> str:
    """A report section; `body` is the HTML the renderer composed."""
    return str(Markup('<section id="{}"><h2>{}</h2>{}</section>').format(anchor, title, Markup(body)))


def page(title: str, heading: str, body: str, description: str = "", nav: Sequence[tuple[str, str]] = (),
         wide: bool = False) -> str:
    """A whole, self-contained page: styles inline, no scripts, nothing fetched. `wide`: the page takes
    the window's width (a page that is one wide table), where a report's prose keeps to 60rem."""
    return _ENV.get_template("page.html").render(title=title, heading=heading, description=description, nav=nav,
                                                 body=Markup(body), style=Markup(STYLE), wide=wide)
