"""PSS/E's layout of the machine records: GENROU's and GENSAL's constants in the order a .dyr
gives them (PSS/E Model Library, "GENROU", "GENSAL"). The writer lays a record out by it and the
reader takes a unit's record on file apart by it: one table, in a module that imports nothing,
so neither the writer nor the reader imports the other for it."""

from __future__ import annotations

PSSE_ORDER = {
    "GENROU": ("Td10", "Td20", "Tq10", "Tq20", "H", "D", "Xd", "Xq", "Xd1", "Xq1", "Xd2", "Xl", "S10", "S12"),
    "GENSAL": ("Td10", "Td20", "Tq20", "H", "D", "Xd", "Xq", "Xd1", "Xd2", "Xl", "S10", "S12"),
}
