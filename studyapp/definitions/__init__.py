"""A study as one file: its definition, written from a study and read back into a new one.

``describe`` writes a study's settings, questions, systems and controls as YAML;
``create`` makes a study from such a file through the checks of the study's pages;
``reading`` reads the file's YAML with the line of every value, refusing hostile text;
``layout`` is the shape both follow.
"""

from studyapp.definitions.create import create_study_from_definition
from studyapp.definitions.describe import definition_yaml, describe_study
from studyapp.definitions.errors import DefinitionError

__all__ = ["DefinitionError", "create_study_from_definition", "definition_yaml", "describe_study"]
