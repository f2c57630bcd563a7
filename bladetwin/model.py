"""The campaign's FE model: the academic twin or a lab's imported model (floor 3: files and manifests).

The model is the campaign's ``[model]``: the academic twin (``family = "academic"``) or a lab's imported FE
model (``family = "imported"``, :func:`rom.importers.model.load_bladed_disk`; docs/campaign.md). Both give a
:class:`rom.academic.BladedDisk`, reduced through the same cache.
"""

from __future__ import annotations

import os
from pathlib import Path

from rom.academic import AcademicParams, BladedDisk, build_bladed_disk
from rom.importers.model import load_bladed_disk, read_model_toml

from .campaign import Campaign, CampaignError, imported_model_table, model_family, read_campaign

__all__ = ["model_params", "load_model", "load_model_file"]


def model_params(campaign: Campaign) -> AcademicParams:
    """The academic twin named by the manifest's ``[model]`` table.

    Raises
    ------
    CampaignError
        The table describes an imported model (:func:`load_model` builds that).
    """
    m = campaign.model
    manifest = campaign.root / "campaign.toml"
    if model_family(m, f"{manifest} [model]") != "academic":
        raise CampaignError(f"{manifest} [model]: an imported model has no academic parameters (load_model "
                            "builds it)")
    try:
        # no disk_scale: the paper's disk, as every manifest written before the key existed was built
        return AcademicParams.for_blades(int(m.get("n_blades", campaign.n_blades)),
                                         disk_scale=float(m.get("disk_scale", 1.0)),
                                         grid=tuple(m.get("grid", campaign.grid)), level=str(m.get("level", "default")))
    except (TypeError, ValueError) as exc:
        raise CampaignError(f"{manifest} [model]: {exc}") from None


def load_model(campaign: Campaign) -> BladedDisk:
    """The FE model of the campaign's ``[model]``: the academic twin, or the imported model it describes.

    An imported model's paths are relative to the campaign folder, or to the TOML file its ``file`` key names
    (:func:`bladetwin.campaign.imported_model_table`). The model must have the campaign's number of blades
    (one slot each) and contact grid.

    Returns
    -------
    rom.academic.BladedDisk
        An :class:`rom.importers.model.ImportedBladedDisk` for an imported model.

    Raises
    ------
    CampaignError, rom.importers.errors.ModelImportError
        One line naming the file and what is wrong: a missing or bad model file, slots or grid other than
        the campaign's.
    """
    manifest = campaign.root / "campaign.toml"
    if model_family(campaign.model, f"{manifest} [model]") == "academic":
        return build_bladed_disk(model_params(campaign))
    table, base, where = imported_model_table(campaign.model, campaign.root, str(manifest))
    bd = load_bladed_disk(table, base, where=where)
    # read_campaign checked the table's n_slots and grid shape where it gives them; the built model is the
    # authority (a grid shape comes from the node sets when the table gives none).
    if bd.n_slots != campaign.n_blades:
        raise CampaignError(f"{where}: [model.placement] n_slots = {bd.n_slots}, but the campaign has n_blades = "
                            f"{campaign.n_blades}")
    if tuple(bd.params.grid) != tuple(campaign.grid):
        raise CampaignError(f"{where}: [model.grids] the model's grids are {bd.params.grid[0]} × "
                            f"{bd.params.grid[1]}, but the campaign's grid is {list(campaign.grid)}")
    return bd


def load_model_file(path: str | os.PathLike) -> BladedDisk:
    """The FE model a file names: a ``model.toml`` (``bladetwin fe export``'s), or a campaign's ``[model]``.

    Parameters
    ----------
    path : path-like
        A TOML file whose ``[model]`` table describes an imported model (paths relative to its folder), or a
        campaign folder or its ``campaign.toml`` (:func:`load_model` of the campaign, academic or imported).

    Raises
    ------
    CampaignError, rom.importers.errors.ModelImportError
        One line naming the file and what is wrong.
    """
    p = Path(path)
    if p.is_dir() or p.name == "campaign.toml":
        return load_model(read_campaign(p if p.is_dir() else p.parent))
    if not p.is_file():
        raise CampaignError(f"{p}: not found (expected a model.toml, a campaign folder or its campaign.toml)")
    return read_model_toml(p)
