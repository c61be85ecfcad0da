"""Numbers in text files, parsed a line per thread: the integer rows of Medit files.

The host finds where each line begins (a newline search); a thread reads the decimal
integers of its line into a row. Lines that hold another count of integers, or anything
but integers and blanks, are flagged and the host hands the file to a slower reader.
"""

import warp as wp

wp.set_module_options({"enable_backward": False})


@wp.func
def is_blank(c: wp.uint8) -> bool:
    """Space, tab, carriage return or newline."""
    return c == wp.uint8(32) or c == wp.uint8(9) or c == wp.uint8(13) or c == wp.uint8(10)


@wp.kernel
def parse_int_rows_kernel(first: int, text: wp.array(dtype=wp.uint8), starts: wp.array(dtype=wp.int64),
                          columns: int, out: wp.array2d(dtype=wp.int64), bad: wp.array(dtype=wp.int8)):
    """A thread takes line i = first + tid, the bytes ``starts[i]`` to ``starts[i + 1]``:
    its ``columns`` integers (an optional sign, then decimal digits, blanks between) into
    ``out[i]``; ``bad[i] = 1`` when the line holds anything else (no digits where a number
    should be, a character that is neither a digit nor blank, a number too many)."""
    i = first + wp.tid()
    at = starts[i]
    end = starts[i + 1]
    flag = wp.int8(0)
    for j in range(columns):
        while at < end and is_blank(text[at]):
            at += wp.int64(1)
        negative = False
        if at < end and (text[at] == wp.uint8(45) or text[at] == wp.uint8(43)):
            negative = text[at] == wp.uint8(45)
            at += wp.int64(1)
        value = wp.int64(0)
        digits = int(0)
        while at < end and text[at] >= wp.uint8(48) and text[at] <= wp.uint8(57):
            value = value * wp.int64(10) + wp.int64(text[at] - wp.uint8(48))
            at += wp.int64(1)
            digits += 1
        if digits == 0 or digits > 18 or (at < end and not is_blank(text[at])):
            flag = wp.int8(1)
        if negative:
            value = -value
        out[i, j] = value
    while at < end:
        if not is_blank(text[at]):
            flag = wp.int8(1)
        at += wp.int64(1)
    bad[i] = flag
