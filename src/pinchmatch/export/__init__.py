"""Stage 4, export: everything written for users and engines: the JSON and CSV documents, glTF
scenes, PNG figures, the viewer page and its server, and the output folder published whole."""
