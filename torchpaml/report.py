"""What a diagnosis writes besides its report (``torchpaml.write_report``): the JSON content of ``diagnosis.json``
and ``discovery.json`` with their schema version, and the text tables."""

from torchpaml._render.schema import SCHEMA_VERSION, diagnosis_to_dict, discovery_to_dict
from torchpaml._render.tables import comparison_table, ranking_table

__all__ = ["SCHEMA_VERSION", "comparison_table", "diagnosis_to_dict", "discovery_to_dict", "ranking_table"]
