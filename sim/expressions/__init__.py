"""Expression libraries (data files ``human.toml``, ``dog.toml``) and their loader."""

from servoface.sim.expressions.library import (
    EXPRESSIONS_DIR,
    Expression,
    ExpressionLibrary,
    get_expression,
    library_path,
    load_library,
)

__all__ = [
    "EXPRESSIONS_DIR",
    "Expression",
    "ExpressionLibrary",
    "get_expression",
    "library_path",
    "load_library",
]
