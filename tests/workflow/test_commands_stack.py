"""The plain undo history: push, undo, redo, macros, merging and the saved state."""
from fluorogui.workflow.session.history import Command, CommandStack


def _stack():
    store = {}
    events = []

    def setter(key, value):
        if value is None:
            store.pop(key, None)
        else:
            store[key] = value

    stack = CommandStack()
    stack.listeners.append(lambda event, entry: events.append(event))
    return stack, store, events, setter


def test_push_undo_redo_and_clean_state():
    stack, store, events, setter = _stack()
    stack.push(Command("a", "k", None, 1, setter))
    stack.push(Command("b", "k", 1, 2, setter))
    assert store == {"k": 2} and stack.dirty and stack.undo_text() == "b"
    stack.set_clean()
    assert not stack.dirty
    stack.undo()
    assert store == {"k": 1} and stack.dirty and stack.redo_text() == "b"
    stack.redo()
    assert store == {"k": 2} and not stack.dirty
    stack.undo()
    stack.undo()
    assert store == {} and not stack.can_undo()
    stack.push(Command("c", "k", None, 5, setter))  # a new branch drops "a"'s redo and the saved state
    assert not stack.can_redo() and stack.dirty and len(stack) == 1
    assert events.count("push") == 3 and events.count("undo") == 3


def test_macro_is_one_step_and_nests():
    stack, store, _, setter = _stack()
    stack.begin_macro("match")
    stack.push(Command("outline", ("o", 0), None, "pts", setter))
    stack.begin_macro("inner")
    stack.push(Command("pose", "p", None, "pose", setter))
    stack.end_macro()
    stack.end_macro()
    assert len(stack) == 1 and stack.undo_text() == "match"
    stack.undo()
    assert store == {}
    stack.redo()
    assert store == {("o", 0): "pts", "p": "pose"}


def test_consecutive_nudges_merge_but_not_into_the_saved_state():
    stack, store, _, setter = _stack()
    stack.push(Command("move", "p", None, 1, setter, merge_id="move"))
    stack.push(Command("move", "p", 1, 2, setter, merge_id="move"))
    assert len(stack) == 1
    stack.set_clean()
    stack.push(Command("move", "p", 2, 3, setter, merge_id="move"))
    assert len(stack) == 2 and stack.dirty
    stack.push(Command("move", "q", None, 9, setter, merge_id="move"))  # another key does not merge
    assert len(stack) == 3
    stack.undo()
    stack.undo()
    assert store == {"p": 2} and not stack.dirty
