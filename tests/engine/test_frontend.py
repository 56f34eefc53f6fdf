"""engine/frontend.py: the memoized front end gives Taichi's own strings and the same compile errors."""

import pytest
import taichi as ti
from taichi.lang.ast import ast_transformer_utils as ast_utils

from taichi_rocks.engine import frontend


@ti.func
def _clamped(x, lo, hi):
    y = x
    if y < lo:
        y = lo
    elif y > hi:
        y = (
            hi
        )
    return y


def _kernel():
    """A fresh kernel (a new instantiation each call) with single- and multi-line nodes, a loop, a branch and an
    inlined ti.func."""
    f = ti.field(ti.f32, 8)

    @ti.kernel
    def fill(scale: ti.f32):
        for i in f:
            v = _clamped(scale * i - 2.0,
                         0.0, 3.0)
            while v > 2.5:
                v -= 1.0
            f[i] = v

    return f, fill


def test_messages_and_results_equal_taichis(taichi_cpu, monkeypatch):
    assert frontend.installed()  # init_taichi installs it
    seen = []
    original = frontend._original["pos"]

    def both(ctx, node):
        mine = frontend._cached_pos_info(ctx, node)
        theirs = original(ctx, node)
        seen.append((mine == theirs, type(node).__name__, node.lineno))
        return mine

    monkeypatch.setattr(ast_utils.ASTTransformerContext, "get_pos_info", both)
    results = []
    for _ in range(2):  # the second compile is served from the memo
        f, fill = _kernel()
        fill(1.5)
        results.append(f.to_numpy())
    assert len(seen) > 50
    assert all(same for same, _, _ in seen), [s for s in seen if not s[0]][:5]
    kinds = {k for _, k, _ in seen}
    assert {"For", "If", "While", "Call", "Return"} <= kinds  # multi-line bodies and calls were quoted
    assert (results[0] == results[1]).all()
    expected = [min(max(1.5 * i - 2.0, 0.0), 3.0) for i in range(8)]
    assert results[0].tolist() == pytest.approx([v - 1.0 if v > 2.5 else v for v in expected])


def test_the_source_prepared_at_each_inlining_is_taichis(taichi_cpu):
    """The memoized file lookup, fills and dedent give the tree, source lines and file Taichi's own do, for a
    kernel and a func, a second time from the memo; and they are installed."""
    import ast

    from taichi.lang import kernel_impl

    assert kernel_impl.textwrap is frontend._Textwrap and kernel_impl.getsourcefile is frontend._cached_source_file
    _, fill = _kernel()
    funcs = [(fill._primal, {"is_kernel": False}), (_clamped.func, {"is_kernel": False})]  # no template args

    def prepared():
        out = []
        for f, kw in funcs:
            tree, ctx = kernel_impl._get_tree_and_ctx(f, **kw)
            out.append((ast.dump(tree, include_attributes=True), ctx.src, ctx.file, ctx.lineno_offset))
        return out

    ours = [prepared(), prepared()]
    frontend.uninstall()
    try:
        theirs = prepared()
    finally:
        frontend.install()
    assert ours[0] == ours[1] == theirs
    assert any("_clamped(scale * i - 2.0," in line for line in theirs[0][1])  # the kernel's own lines


def _broken():
    @ti.kernel
    def bad() -> ti.i32:
        x = 1
        return x + undefined_name  # noqa: F821

    return bad


def test_a_compile_error_reads_the_same(taichi_cpu):
    messages = []
    for on in (True, False):
        (frontend.install if on else frontend.uninstall)()
        with pytest.raises(ti.TaichiCompilationError) as err:
            _broken()()
        messages.append(str(err.value))
    frontend.install()
    assert messages[0] == messages[1]
    assert "undefined_name" in messages[0] and "^" in messages[0] and "test_frontend.py" in messages[0]


def test_the_class_body_check_answers_as_taichis(monkeypatch):
    """frontend.install_decorators: a kernel and a func in a data-oriented class body are class members, at module
    level (and in a function) they are not; Taichi's own check, called at the same place, says the same."""
    from taichi.lang import kernel_impl

    answers = []

    def both(level_of_class_stackframe):
        # called where Taichi calls its check: one frame deeper for the two below, hence the + 1
        ours = frontend._inside_class(level_of_class_stackframe + 1)
        theirs = frontend._original["inside_class"](level_of_class_stackframe + 1)
        answers.append((ours, theirs))
        return theirs

    monkeypatch.setattr(kernel_impl, "_inside_class", both)

    @ti.data_oriented
    class Holder:
        @ti.kernel
        def k(self):
            pass

        @ti.func
        def f(self):
            pass

    @ti.kernel
    def loose():
        pass

    @ti.func
    def loose_func():
        pass

    assert answers == [(True, True), (True, True), (False, False), (False, False)], answers
    assert Holder and loose and loose_func
