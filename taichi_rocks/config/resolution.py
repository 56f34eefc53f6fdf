"""The frame-size rule, in one place: width and height are even integers >= 16 (H.264 in yuv420p needs even
sides). The scene models derive their constraint from :data:`MIN_SIDE` and :data:`SIDE_MULTIPLE`; the command
line and the renderer call :func:`check_resolution` / :func:`parse_resolution`."""

__all__ = ["MIN_SIDE", "SIDE_MULTIPLE", "check_resolution", "parse_resolution"]

MIN_SIDE = 16
SIDE_MULTIPLE = 2


def check_resolution(res) -> tuple[int, int]:
    """(width, height) as even ints >= 16, or ValueError with a clear message."""
    try:
        w, h = (int(x) for x in res)
    except Exception:
        raise ValueError(f"resolution must be [width, height], got {res!r}") from None
    if w < MIN_SIDE or h < MIN_SIDE or w % SIDE_MULTIPLE or h % SIDE_MULTIPLE:
        raise ValueError(f"resolution must be two even integers >= {MIN_SIDE} (H.264 in yuv420p needs even "
                         f"sides), got {w}x{h}")
    return w, h


def parse_resolution(text: str) -> tuple[int, int]:
    """"WIDTHxHEIGHT" (such as 1280x720) -> (width, height) by :func:`check_resolution`, or ValueError."""
    try:
        w, h = (int(x) for x in text.lower().split("x"))
    except ValueError:
        raise ValueError(f"expected WIDTHxHEIGHT such as 1280x720, got {text!r}") from None
    return check_resolution((w, h))
