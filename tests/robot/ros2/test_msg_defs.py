"""``--msg-def``: a robot's own message definitions are read without ever running code built from them.

Issue 41, point 7: a type that holds itself, an A -> B -> A pair, a 1,200-deep chain, fields named
``def``/``class``/``lambda`` ended in internal errors (RecursionError, SyntaxError from generated
code); ``/etc/passwd`` was quoted whole, twice; a directory or a device read "no such file". Each is now
one line (``ValueError``, status 2 on the command line) that quotes at most the offending line, before
any code is generated from the names. Torch-free. Needs the optional extra ``ros``.
"""

from __future__ import annotations

import os

import pytest

from tactile_torch.cli import BAD_INPUT_EXIT, main
from tactile_torch.robot.ros2.message_types import (
    MAX_MESSAGE_DEPTH,
    MessageDefinition,
    message_types,
    read_message_definition,
)
from tests.stream_helpers import energy_bundle

pytest.importorskip("rosbags", reason="the optional extra 'ros' (rosbags) is not installed")


def _write(tmp_path, name, text):
    path = tmp_path / "pkg" / "msg" / f"{name}.msg"
    path.parent.mkdir(parents=True, exist_ok=True)
    path.write_text(text)
    return path


@pytest.mark.parametrize(
    ("files", "match"),
    [
        (
            {"Self": "std_msgs/Header header\npkg/Self child\n"},
            r"pkg/msg/Self holds itself \(pkg/msg/Self -> pkg/msg/Self\)",
        ),
        (
            {"A": "pkg/B b\n", "B": "float32 x\npkg/A a\n"},
            r"holds itself \(pkg/msg/(A -> pkg/msg/B -> pkg/msg/A|B -> pkg/msg/A -> pkg/msg/B)\)",
        ),
        (
            {"Kw": "float32 x\nfloat32[] class\n"},
            r"Kw\.msg line 2: 'class' is a Python keyword.*: 'float32\[\] class'$",
        ),
        ({"Kw": "int32 lambda\n"}, r"line 1: 'lambda' is a Python keyword"),
        ({"Kw": "def/Thing value\n"}, r"line 1: 'def' is a Python keyword"),
        (
            {"Bad": "# a comment\n\nfloat32 ok\na:b c\n"},
            r"Bad\.msg line 4: not a field .*: 'a:b c'$",
        ),
    ],
)
def test_definitions_that_cannot_be_built_are_one_line(tmp_path, files, match):
    paths = [_write(tmp_path, name, text) for name, text in files.items()]
    with pytest.raises(ValueError, match=match) as refused:  # as the file is read, or as the types are built
        message_types([read_message_definition(path) for path in paths])
    assert "\n" not in str(refused.value) and len(str(refused.value)) < 300


def test_a_chain_deeper_than_the_bound_is_refused_without_recursing(tmp_path):
    n = 200  # the chain was 1,200 deep; the bound is what matters
    definitions = [
        read_message_definition(
            _write(tmp_path, f"C{i}", f"pkg/C{i + 1} next\n" if i < n - 1 else "float32[] v\n")
        )
        for i in range(n)
    ]
    with pytest.raises(ValueError, match=rf"nests messages more than {MAX_MESSAGE_DEPTH} deep"):
        message_types(definitions)
    # as deep as the bound is read
    deep = [MessageDefinition(f"pkg/D{i + 1} next\n", f"pkg/msg/D{i}") for i in range(MAX_MESSAGE_DEPTH - 1)]
    store = message_types([*deep, MessageDefinition("float32[] v\n", f"pkg/msg/D{MAX_MESSAGE_DEPTH - 1}")])
    assert "pkg/msg/D0" in store.fielddefs


def test_a_file_that_is_no_definition_is_quoted_one_line_at_most(tmp_path):
    text = "".join(f"user{i}:x:{i}:{i}::/home/user{i}:/bin/sh\n" for i in range(200))
    path = tmp_path / "passwd"
    path.write_text(text)
    with pytest.raises(ValueError) as refused:
        message_types([read_message_definition(f"pkg/msg/P={path}")])
    assert (
        str(refused.value)
        == f"{path} line 1: not a field of a message definition (TYPE NAME): 'user0:x:0:0::/home/user0:/bin/sh'"
    )


def test_a_directory_or_a_device_is_named_for_what_it_is(tmp_path):
    with pytest.raises(ValueError, match=r"is a directory, expected a message definition \(\.msg\) file"):
        read_message_definition(tmp_path)
    with pytest.raises(ValueError, match=r"/dev/null: is a device, expected a message definition"):
        read_message_definition("pkg/msg/N=/dev/null")
    fifo = tmp_path / "fifo.msg"
    os.mkfifo(fifo)
    with pytest.raises(ValueError, match=r"fifo\.msg: is a FIFO, expected a message definition"):
        read_message_definition(fifo)  # never opened: it would block


@pytest.mark.parametrize("model", ["dir", "fifo", "/dev/null"])
def test_a_model_that_is_no_file_is_one_line(tmp_path, capsys, model):
    path = {"dir": tmp_path, "fifo": tmp_path / "m.onnx", "/dev/null": "/dev/null"}[model]
    if model == "fifo":
        os.mkfifo(path)
    assert main(["stream", "--model", str(path), "--port", "loop://"]) == BAD_INPUT_EXIT
    err = capsys.readouterr().err
    what = {"dir": "a directory", "fifo": "a FIFO", "/dev/null": "a device"}[model]
    assert err == f"tactile-torch stream: {path}: is {what}, expected an exported .onnx bundle\n"


def test_a_keyword_field_on_the_command_line_is_status_2(tmp_path, capsys):
    pytest.importorskip("cyclonedds", reason="the optional extra 'ros2' (cyclonedds) is not installed")
    msg = _write(tmp_path, "Kw", "float32[] def\n")
    model = energy_bundle(tmp_path / "m.onnx", window=16)
    argv = [
        "stream",
        "--model",
        str(model),
        "--ros2-topic",
        "/x",
        "--ros2-type",
        "pkg/msg/Kw",
        "--field",
        "def",
    ]
    assert main([*argv, "--msg-def", str(msg)]) == BAD_INPUT_EXIT
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and "Kw.msg line 1: 'def' is a Python keyword" in err
