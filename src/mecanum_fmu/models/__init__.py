"""The bundled models: their maths (blocks/), pythonfmu slaves (slaves/), catalog, build and lookup."""
