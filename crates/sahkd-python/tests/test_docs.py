"""Every public call of the package carries a docstring, so help() explains it."""

import pydoc

import sahkd


def public(owner):
    return [n for n in dir(owner) if not n.startswith("_")]


def test_every_public_call_and_result_type_has_a_docstring():
    missing = []
    for owner in (sahkd.KdTree, sahkd.Scene):
        for name in public(owner):
            doc = getattr(owner, name).__doc__
            if not (doc and doc.strip()):
                missing.append(f"{owner.__name__}.{name}")
    for name in sahkd.__all__:
        obj = getattr(sahkd, name)
        if callable(obj) and not (obj.__doc__ and obj.__doc__.strip()):
            missing.append(name)
    assert not missing, f"no docstring: {missing}"


def test_help_shows_the_signature_and_docstring():
    text = pydoc.render_doc(sahkd.KdTree.intersect, renderer=pydoc.plaintext)
    assert "origins, directions" in text and "closest hit" in text
    text = pydoc.render_doc(sahkd.load, renderer=pydoc.plaintext)
    assert "load(path)" in text and "Reads a tree saved by KdTree.save" in text
