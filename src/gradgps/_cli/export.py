"""``gradgps export [MODEL_DIR] --onnx model.onnx``: the network as ONNX, for other runtimes."""

from __future__ import annotations

from pathlib import Path

import click

from .options import option

__all__ = ["export"]


@click.command()
@click.argument(
    "model_dir",
    required=False,
    default=None,
    type=click.Path(exists=True, file_okay=False, path_type=Path),
)
@option("--onnx", "onnx_path", path="file", required=True, help="ONNX file to write")
def export(model_dir: Path | None, onnx_path: Path) -> None:
    """Export the GRU network of MODEL_DIR (default: the shipped model) to ONNX.

    \b
    The graph takes the GRAD *feature vectors*, not fixes:
      inputs   features (time, batch, F) float32, unscaled, as gradgps computes
               them (names in the model metadata 'feature_names'); h1_in
               (1, batch, 32) and h2_in (1, batch, 16), zeros at a segment start
      outputs  anomaly_probability (time, batch), bias_probabilities
               (time, batch, K) (classes in metadata 'bias_classes'), h1_out,
               h2_out (feed them back in to continue the stream)
    Feature extraction, REMA, the time classifier and recovery stay in gradgps;
    the anomaly threshold is in metadata 'anomaly_threshold' (and, for files
    sampled slowly, 'thresholds_by_rate': JSON bands that replace it from their
    'from_period_s' seconds between fixes on). Needs the extra
    'onnx' (pip install 'gradgps[onnx]').
    """
    try:
        import onnx  # noqa: F401
    except ImportError:
        raise click.ClickException(
            "ONNX export needs the onnx package: pip install 'gradgps[onnx]'"
        ) from None
    from .._train.onnx_export import export_onnx

    path = export_onnx(model_dir, onnx_path)
    click.echo(f"wrote {path} ({path.stat().st_size / 1024:.0f} KiB)")
