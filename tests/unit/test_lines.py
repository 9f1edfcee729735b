"""Lines as YARP's InputStream::readLine reads them."""

import pytest

from yarp_lite.lines import split_line


@pytest.mark.parametrize("data, expected", [
    (b"abc\r\n", ("abc", 5)), (b"a\0b\n", ("ab", 4)), (b"abc", None),
    (b"first\\\nsecond\nrest", ("firstsecond", 14)),      # backslash-newline continues
    (b"a\\b\n", ("a\\b", 4)), (b"a\\\\\n", ("a\\\\", 4)),  # other backslashes are kept
])
def test_split_line(data, expected):
    assert split_line(data) == expected


def test_offsets():
    assert split_line(b"xxone\ntwo\n", 2) == ("one", 6)
