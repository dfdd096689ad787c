"""Pure UFL weak forms of the cell, macro and micro problems (imports ufl only)."""
