"""MkDocs hook: the repository's measured results (results/: reports, tables, figures) and examples/ published with
the site, at the same paths, so pages link to them as files and `mkdocs build --strict` checks those links too."""

from pathlib import Path

from mkdocs.structure.files import File

FOLDERS = {"results": (".md", ".png", ".txt", ".json"), "examples": (".py", ".ipynb", ".yaml", ".obj")}
FILES = ["app/samplers/README.md"]  # the samplers' notes: the paper's open choices and the readings taken


def on_files(files, config):
    root = Path(config["config_file_path"]).parent
    paths = [root / name for name in FILES]
    for folder, suffixes in FOLDERS.items():
        paths += [p for p in sorted((root / folder).rglob("*")) if p.is_file() and p.suffix in suffixes]
    for path in paths:
        uri = path.relative_to(root).as_posix()
        files.append(File(uri, str(root), config["site_dir"], config["use_directory_urls"]))
    return files
