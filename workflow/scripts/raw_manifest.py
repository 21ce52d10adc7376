"""Write the manifest (every file's sha256) of a bench dataset folder; raw/ is only read."""

from spa.io import get_logger
from spa.pipeline.provenance import write_manifest

log = get_logger("raw_manifest", snakemake.log[0])
manifest = write_manifest(
    snakemake.params.folder, snakemake.output.manifest, cache=snakemake.params.cache
)
log.info("%s: %d files, digest %s", manifest["folder"], len(manifest["files"]), manifest["digest"])
