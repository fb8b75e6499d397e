"""The pages' DEFLATE decoder (``sidprep.view.page.INFLATE_JS``, RFC 1951) run in headless Chromium
on streams packed by Python's zlib (raw DEFLATE): stored, fixed-Huffman and dynamic-Huffman blocks,
a stream mixing all three between flushes, overlapping copies, an empty input and plotly.js itself;
a damaged stream must raise an error, not hang or return bytes.

Independent reference: the original bytes, by length and CRC-32 (zlib.crc32 here, the page's own
bitwise CRC-32 there).
"""

import base64
import json
import subprocess
import zlib
from pathlib import Path

import numpy as np
import pytest

from sidprep.view.page import INFLATE_JS, deflate, plotly_js
from test_view import BROWSER_TIMEOUT_S, QUIET_BROWSER, browser

#: BTYPE of a DEFLATE block header (RFC 1951 3.2.3)
STORED, FIXED, DYNAMIC = 0, 1, 2

_PROBE = """<!DOCTYPE html><html><head><meta charset="utf-8"><title>probe</title></head><body>
<script>
%s
function crc32(bytes) {               // CRC-32 (ISO-HDLC, as zlib.crc32), bit by bit
  let crc = -1;
  for (let i = 0; i < bytes.length; i++) {
    crc ^= bytes[i];
    for (let k = 0; k < 8; k++) crc = (crc >>> 1) ^ (0xedb88320 & -(crc & 1));
  }
  return (crc ^ -1) >>> 0;
}
const cases = %s, result = {};
for (const [name, [packed, size]] of Object.entries(cases)) {
  const text = atob(packed), bytes = new Uint8Array(text.length);
  for (let i = 0; i < text.length; i++) bytes[i] = text.charCodeAt(i);
  try {
    const sized = inflate(bytes, size), grown = inflate(bytes);   // output sized as the pages do, and grown
    result[name] = [sized.length, crc32(sized), grown.length, crc32(grown)];
  } catch (error) {
    result[name] = String(error);
  }
}
document.title = JSON.stringify(result);
</script></body></html>
"""


def block_type(stream: bytes) -> int:
    """BTYPE of a raw DEFLATE stream's first block."""
    return (stream[0] >> 1) & 3


def words(rng, count: int) -> bytes:
    """Text of ``count`` words drawn from a small vocabulary (compresses with dynamic codes)."""
    vocabulary = np.array("mode shape stiffness mass modal reduced body surface frame node stress page".split())
    return " ".join(rng.choice(vocabulary, count)).encode()


def mixed(rng) -> tuple[bytes, bytes]:
    """Text, random bytes and text in one stream, flushed between them (a sync and a full flush:
    empty stored blocks), so dynamic, stored and fixed blocks follow each other."""
    text, noise, tail = words(rng, 5000), rng.bytes(70_000), b"end of stream"
    packer = zlib.compressobj(6, zlib.DEFLATED, -15)
    stream = (packer.compress(text) + packer.flush(zlib.Z_SYNC_FLUSH) + packer.compress(noise)
              + packer.flush(zlib.Z_FULL_FLUSH) + packer.compress(tail) + packer.flush())
    return text + noise + tail, stream


def inflated_in_chromium(streams: dict, tmp_path: Path) -> dict:
    """{name: [length, CRC-32] twice (output sized, output grown) or the error's text} of each raw
    DEFLATE stream of ``streams`` ({name: (stream, original length)}), inflated by INFLATE_JS in
    headless Chromium (virtual time, as the page tests)."""
    cases = {name: [base64.b64encode(stream).decode("ascii"), size] for name, (stream, size) in streams.items()}
    probe = tmp_path / "inflate.html"
    probe.write_text(_PROBE % (INFLATE_JS, json.dumps(cases)), encoding="utf-8")
    run = subprocess.run([browser(), *QUIET_BROWSER, f"--user-data-dir={tmp_path / 'profile'}", "--virtual-time-budget=1000",
                          "--dump-dom", probe.resolve().as_uri()], capture_output=True, text=True, timeout=BROWSER_TIMEOUT_S)
    title = run.stdout.split("<title>", 1)[1].split("</title>", 1)[0]
    return json.loads(title.replace("&quot;", '"').replace("&amp;", "&").replace("&lt;", "<").replace("&gt;", ">"))


@pytest.mark.skipif(browser() is None, reason="Chromium not installed (apt-get install chromium)")
def test_inflate_in_chromium_matches_zlib(tmp_path):
    rng = np.random.default_rng(0)
    originals = {"stored": rng.bytes(200_000),                  # level 0: stored blocks of at most 65535 bytes
                 "fixed": bytes(range(256)) * 2,                # short: every literal (8- and 9-bit codes), one copy
                 "dynamic": words(rng, 100_000),
                 "overlapping": b"a" * 100_000,                 # copies of distance 1, length 258
                 "empty": b"",
                 "plotly.js": plotly_js().encode("utf-8")}
    streams = {name: deflate(raw, 0 if name == "stored" else 9) for name, raw in originals.items()}
    assert block_type(streams["stored"]) == STORED and block_type(streams["fixed"]) == FIXED
    assert block_type(streams["dynamic"]) == DYNAMIC and block_type(streams["plotly.js"]) == DYNAMIC
    originals["mixed"], streams["mixed"] = mixed(rng)
    cases = {name: (stream, len(originals[name])) for name, stream in streams.items()}
    # damaged: cut short inside a block, and a block type 3 (reserved)
    cases["truncated"] = (streams["dynamic"][:len(streams["dynamic"]) // 2], len(originals["dynamic"]))
    cases["reserved type"] = (bytes([0b111]), 0)
    result = inflated_in_chromium(cases, tmp_path)
    for name, raw in originals.items():
        expected = [len(raw), zlib.crc32(raw)]
        assert result[name] == expected + expected, name
    assert result["truncated"].startswith("Error: inflate: the input ends inside a block")
    assert result["reserved type"].startswith("Error: inflate: invalid block type 3")
