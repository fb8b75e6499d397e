"""One self-contained HTML page (plotly.js inlined, opens offline by double-click): the layout
shared by the mode page (modes.py) and the mechanism page (mechanism.py), its side tables, the
colour bar placed clear of plotly's toolbar, and the compact number arrays the pages' scripts read.

plotly.js, the figure and the page's data travel packed: raw DEFLATE (RFC 1951, Python's zlib)
in base64, inflated synchronously by the page's own decoder (INFLATE_JS) before plotly.js runs.
"""

from __future__ import annotations

import base64
import functools
import html
import json
import zlib
from pathlib import Path

import numpy as np

from sidprep.sid.io.atomic import atomic_path

#: the pages show stresses in MPa
PA_PER_MPA = 1e6
PLOT_ID = "sidprep-plot"
#: significant digits of the numbers a page's script reads (positions, shapes, stresses, q):
#: 1e-5 of each array's largest magnitude, below what a screen shows
PAGE_DIGITS = 5
#: the colour bar spans this fraction of the plot's height, centred below plotly's toolbar (which
#: takes the plot's top right corner), with its title beside it, not above it
COLORBAR_LENGTH = 0.75
COLORBAR_CENTRE = 0.45
#: zlib level of plotly.js, packed once per process (4.8 MB -> 1.47 MB raw DEFLATE, 0.18 CPU-s)
PLOTLY_LEVEL = 9
#: zlib level of a page's figure and data, packed per page: the engine's stress data, 3.8 MB of
#: JSON, -> 1.14 MB in 0.06 CPU-s at level 4 (level 6: 1.06 MB in 0.29 CPU-s, 9: 1.02 MB in 2.4)
PAGE_LEVEL = 4

_PAGE = """<!DOCTYPE html>
<html><head><meta charset="utf-8"><title>{title}</title>
<style>
body {{ font-family: sans-serif; margin: 0; display: flex; height: 100vh; }}
#main {{ flex: 1; min-width: 0; display: flex; flex-direction: column; }}
#controls {{ padding: 6px; background: #eee; }}
#side {{ flex: 0 0 360px; overflow: auto; padding: 8px; font-size: 12px; border-left: 1px solid #ccc; }}
table {{ border-collapse: collapse; width: 100%; }} th, td {{ text-align: left; padding: 2px 4px;
vertical-align: top; border-bottom: 1px solid #ddd; }}
.ok {{ color: green; }} .FAIL {{ color: red; font-weight: bold; }} .info {{ color: grey; }}
#{plot_id} {{ flex: 1; min-height: 0; }}
</style></head><body>
<div id="main"><div id="controls">{controls}</div><div id="{plot_id}"></div></div>
<div id="side"><h3>{title}</h3>{side}</div>
{figure}
{data}
{plotly}
"""

#: a synchronous raw-DEFLATE decoder (RFC 1951): inflate(bytes, size) returns the inflated
#: bytes (a Uint8Array; size, the expected length, sizes the output, which grows if it was short)
INFLATE_JS = r"""
const LENGTH_BASE = [3, 4, 5, 6, 7, 8, 9, 10, 11, 13, 15, 17, 19, 23, 27, 31, 35, 43, 51, 59, 67, 83, 99, 115,
                     131, 163, 195, 227, 258];                                        // RFC 1951 3.2.5
const LENGTH_EXTRA = [0, 0, 0, 0, 0, 0, 0, 0, 1, 1, 1, 1, 2, 2, 2, 2, 3, 3, 3, 3, 4, 4, 4, 4, 5, 5, 5, 5, 0];
const DIST_BASE = [1, 2, 3, 4, 5, 7, 9, 13, 17, 25, 33, 49, 65, 97, 129, 193, 257, 385, 513, 769, 1025, 1537,
                   2049, 3073, 4097, 6145, 8193, 12289, 16385, 24577];
const DIST_EXTRA = [0, 0, 0, 0, 1, 1, 2, 2, 3, 3, 4, 4, 5, 5, 6, 6, 7, 7, 8, 8, 9, 9, 10, 10, 11, 11, 12, 12, 13, 13];
// order of the code length code's lengths in a dynamic block header (RFC 1951 3.2.7)
const CLEN_ORDER = [16, 17, 18, 0, 8, 7, 9, 6, 10, 5, 11, 4, 12, 3, 13, 2, 14, 1, 15];

// The canonical Huffman code of the code lengths (RFC 1951 3.2.2) as a lookup table indexed by
// the next `bits` input bits: entry = symbol << 4 | code length (0: no code starts so).
function huffman(lengths) {
  let bits = 0;
  const count = new Array(16).fill(0), next = new Array(16).fill(0);
  for (const n of lengths) { count[n]++; bits = Math.max(bits, n); }
  count[0] = 0;
  for (let n = 1, code = 0; n < 16; n++) { code = (code + count[n - 1]) << 1; next[n] = code; }
  const table = new Int32Array(1 << bits);
  for (let symbol = 0; symbol < lengths.length; symbol++) {
    const n = lengths[symbol];
    if (!n) continue;
    // codes are packed first bit first (RFC 1951 3.1.1): index by the code's bits reversed
    let code = next[n]++, reversed = 0;
    for (let i = 0; i < n; i++) { reversed = (reversed << 1) | (code & 1); code >>= 1; }
    for (let i = reversed; i < table.length; i += 1 << n) table[i] = (symbol << 4) | n;
  }
  return {table, bits};
}

let FIXED = null;       // the fixed Huffman codes (RFC 1951 3.2.6), made at their first use

function inflate(input, size) {
  let out = new Uint8Array(Math.max(size || 0, 1024)), n = 0;    // output and its length
  let pos = 0, buffer = 0, held = 0;     // next input byte; bits read but not used, and their count
  function room(k) {                     // out holds k more bytes
    if (n + k <= out.length) return;
    const grown = new Uint8Array(Math.max(2 * out.length, n + k));
    grown.set(out.subarray(0, n));
    out = grown;
  }
  function bits(k) {                     // the next k bits (k <= 16), first bit lowest
    while (held < k) {
      if (pos >= input.length) throw new Error('inflate: the input ends inside a block');
      buffer |= input[pos++] << held;
      held += 8;
    }
    const value = buffer & ((1 << k) - 1);
    buffer >>>= k;
    held -= k;
    return value;
  }
  function decode(code) {                // the next symbol of a huffman() code
    while (held < code.bits && pos < input.length) { buffer |= input[pos++] << held; held += 8; }
    const entry = code.table[buffer & ((1 << code.bits) - 1)], length = entry & 15;
    if (length === 0 || length > held) {
      throw new Error(held < code.bits ? 'inflate: the input ends inside a block' : 'inflate: invalid Huffman code');
    }
    buffer >>>= length;
    held -= length;
    return entry >> 4;
  }
  function codes(literals, distances) {  // a compressed block's data (RFC 1951 3.2.5)
    for (;;) {
      const symbol = decode(literals);
      if (symbol < 256) { room(1); out[n++] = symbol; continue; }
      if (symbol === 256) return;
      const s = symbol - 257;           // a length, its extra bits, then a distance, its extra bits
      if (s >= 29) throw new Error('inflate: invalid length code');
      const length = LENGTH_BASE[s] + bits(LENGTH_EXTRA[s]), d = decode(distances);
      if (d >= 30) throw new Error('inflate: invalid distance code');
      const distance = DIST_BASE[d] + bits(DIST_EXTRA[d]);
      if (distance > n) throw new Error('inflate: distance before the start of the output');
      room(length);
      for (let i = 0; i < length; i++, n++) out[n] = out[n - distance];   // copies may overlap
    }
  }
  function dynamic() {                   // a dynamic block's codes (RFC 1951 3.2.7)
    const nlit = bits(5) + 257, ndist = bits(5) + 1, nclen = bits(4) + 4;
    const clen = new Array(19).fill(0);
    for (let i = 0; i < nclen; i++) clen[CLEN_ORDER[i]] = bits(3);
    const lengthCode = huffman(clen), lengths = [];
    while (lengths.length < nlit + ndist) {
      const symbol = decode(lengthCode);
      if (symbol < 16) { lengths.push(symbol); continue; }
      if (symbol === 16 && !lengths.length) throw new Error('inflate: repeat without a length');
      const [value, repeat] = symbol === 16 ? [lengths[lengths.length - 1], 3 + bits(2)]
                            : symbol === 17 ? [0, 3 + bits(3)] : [0, 11 + bits(7)];
      for (let i = 0; i < repeat; i++) lengths.push(value);
    }
    if (lengths.length > nlit + ndist) throw new Error('inflate: code lengths overrun');
    return [huffman(lengths.slice(0, nlit)), huffman(lengths.slice(nlit))];
  }
  let last = 0;
  while (!last) {                        // blocks (RFC 1951 3.2.3): BFINAL, then BTYPE
    last = bits(1);
    const type = bits(2);
    if (type === 0) {                    // stored (3.2.4): skip to a byte boundary, LEN, NLEN, bytes
      bits(held & 7);
      const length = bits(16);
      if ((bits(16) ^ 0xffff) !== length) throw new Error('inflate: stored block length check fails');
      pos -= held >> 3;                  // whole bytes still held go back to the input
      buffer = 0;
      held = 0;
      if (pos + length > input.length) throw new Error('inflate: the input ends inside a block');
      room(length);
      out.set(input.subarray(pos, pos + length), n);
      pos += length;
      n += length;
    } else if (type === 1) {
      if (!FIXED) {
        const lengths = [];
        for (let i = 0; i < 288; i++) lengths.push(i < 144 ? 8 : i < 256 ? 9 : i < 280 ? 7 : 8);
        FIXED = [huffman(lengths), huffman(new Array(30).fill(5))];
      }
      codes(FIXED[0], FIXED[1]);
    } else if (type === 2) codes(...dynamic());
    else throw new Error('inflate: invalid block type 3');
  }
  return out.subarray(0, n);
}
"""

#: plotly.js inflated and run first, then the figure drawn from its JSON and the page's own script
#: run as start(D, gd) with its data D and the plot element gd
_LOADER = """<script>
{inflate}
function unpack(id) {
  const element = document.getElementById(id), text = atob(element.textContent);
  const bytes = new Uint8Array(text.length);
  for (let i = 0; i < text.length; i++) bytes[i] = text.charCodeAt(i);
  return new TextDecoder().decode(inflate(bytes, Number(element.dataset.bytes)));
}
{                                        // its time: the measure 'inflate plotly.js' (User Timing)
  const begun = performance.now(), plotly = document.createElement('script');
  plotly.text = unpack('plotly-js');
  performance.measure('inflate plotly.js', {start: begun});
  document.head.appendChild(plotly);
}
</script>
<script>
function start(D, gd) {
{script}
}
(() => {
  const F = JSON.parse(unpack('figure'));
  const gd = document.getElementById('{plot_id}');
  Plotly.newPlot(gd, F.data, F.layout, {responsive: true}).then(() => start(JSON.parse(unpack('data')), gd));
})();
</script>
</body></html>
"""


def deflate(raw: bytes, level: int) -> bytes:
    """Raw DEFLATE (RFC 1951: no zlib or gzip header) of ``raw``, what the page's inflate() reads."""
    packer = zlib.compressobj(level, zlib.DEFLATED, -15)
    return packer.compress(raw) + packer.flush()


def packed(part: str, text: str, level: int = PAGE_LEVEL) -> str:
    """The <script> element of one packed page part: ``text`` as UTF-8, deflated and base64, with
    its length in bytes (data-bytes) to size the page's output buffer."""
    raw = text.encode("utf-8")
    return (f'<script type="application/octet-stream" id="{part}" data-bytes="{len(raw)}">'
            f'{base64.b64encode(deflate(raw, level)).decode("ascii")}</script>')


@functools.lru_cache(maxsize=1)
def plotly_js() -> str:
    """plotly.js (4.8 MB)."""
    from plotly.offline import get_plotlyjs  # deferred: 0.25 s import, pages only

    return get_plotlyjs()


@functools.lru_cache(maxsize=1)
def packed_plotly() -> str:
    """plotly.js as every page carries it (1.96 MB), packed once per process."""
    return packed("plotly-js", plotly_js(), PLOTLY_LEVEL)


def colorbar(title: str) -> dict:
    """plotly colour-bar settings: ``title`` beside the bar, the bar clear of the toolbar."""
    return dict(title=dict(text=title, side="right"), len=COLORBAR_LENGTH, y=COLORBAR_CENTRE, yanchor="middle")


def frame_axes(length: float, label: str) -> list:
    """plotly traces of a frame's x, y, z axes (red, green, blue) of ``length`` from the origin,
    tipped with their names (e.g. "K x" for the body frame, "ground x" for the inertial frame)."""
    import plotly.graph_objects as go  # deferred: 0.25 s import, pages only

    traces = []
    for a, colour in enumerate(("red", "green", "blue")):
        end = np.zeros(3)
        end[a] = length
        traces.append(go.Scatter3d(x=[0, end[0]], y=[0, end[1]], z=[0, end[2]], mode="lines+text",
                                   text=["", "xyz"[a]], line=dict(color=colour, width=6), name=f"{label} {'xyz'[a]}",
                                   hoverinfo="name"))
    return traces


def axis_titles(length_unit: str) -> dict:
    """The 3-D scene's axis titles with the length unit, e.g. "x (m)"."""
    return {f"{a}axis": dict(title=dict(text=f"{a} ({length_unit})")) for a in "xyz"}


def table(rows: list[tuple[str, str]]) -> str:
    """An HTML table of (heading, cell) rows; headings are escaped, cells are HTML."""
    return "<table>" + "".join(f"<tr><th>{html.escape(k)}</th><td>{v}</td></tr>" for k, v in rows) + "</table>"


def js_array(values, digits: int = PAGE_DIGITS) -> str:
    """A flat JavaScript array literal of ``values`` (any shape, C order) to ``digits`` significant
    digits of the array's largest magnitude (fixed step, so small entries cost few characters)."""
    a = np.asarray(values, float).ravel()
    if not np.isfinite(a).all():
        raise ValueError("a page array holds non-finite values")
    peak = float(np.abs(a).max()) if a.size else 0.0
    if peak == 0.0:
        return "[" + ",".join(["0"] * a.size) + "]"
    step = 10.0 ** (np.floor(np.log10(peak)) - digits + 1)
    counts = np.rint(a / step).astype(np.int64)
    exponent = int(round(np.log10(step)))
    # integers times 10**exponent, written as e.g. 1234e-7: exact decimal, no float repr noise
    suffix = f"e{exponent}" if exponent else ""
    return "[" + ",".join(f"{c}{suffix}" if c else "0" for c in counts.tolist()) + "]"


def js_object(members: dict[str, str]) -> str:
    """A JavaScript object literal of members already written as JavaScript values."""
    return "{" + ",".join(f"{json.dumps(k)}:{v}" for k, v in members.items()) + "}"


def page_part(path, part: str) -> str:
    """The text of one packed part of a page written by ``write_page``: "figure" (the plotly
    figure's JSON), "data" (the JSON of its D) or "plotly-js"."""
    text = Path(path).read_text(encoding="utf-8")
    start = text.index(f'id="{part}"')
    start = text.index(">", start) + 1
    raw = base64.b64decode(text[start:text.index("</script>", start)])
    return zlib.decompress(raw, -15).decode("utf-8")


def page_data(path) -> dict:
    """The data object D of a page written by ``write_page`` (for scripts and tests)."""
    return json.loads(page_part(path, "data"))


def write_page(path, title: str, figure, controls: str, side: str, script: str, data: str) -> Path:
    """Write one self-contained HTML page atomically (plotly.js inlined: it opens offline by
    double-click); returns the path.

    figure : a plotly Figure; controls, side : HTML of the control bar and the side panel;
    script : JavaScript run as start(D, gd) once the figure is drawn; data : the JSON text of D.
    """
    text = _PAGE.format(title=html.escape(title), plot_id=PLOT_ID, controls=controls, side=side,
                        figure=packed("figure", figure.to_json()), data=packed("data", data),
                        plotly=packed_plotly())
    text += _LOADER.replace("{script}", script).replace("{plot_id}", PLOT_ID).replace("{inflate}", INFLATE_JS)
    path = Path(path)
    with atomic_path(path) as tmp:
        Path(tmp).write_text(text, encoding="utf-8")
    return path
