"""The trackside terminal UI (Textual). The only part of ``station`` that imports textual."""
