//! The comparison's live plots: MSE and relMSE against time, log-log, a line per strategy,
//! with the reference's noise floor.

use egui::{Color32, Ui};
use egui_plot::{Corner, GridMark, HLine, HoverPosition, Legend, Line, LineStyle, Plot};

use super::{CompareView, strategy_colour};
use crate::compare::ConvergencePoint;
use crate::compare::report::{sci, tick_label};
use crate::light::Strategy;

impl CompareView {
    pub(super) fn plots(&self, ui: &mut Ui) {
        let floor = self
            .frame
            .as_ref()
            .and_then(|f| f.reference())
            .and_then(|r| r.info.as_ref())
            .map(|i| i.convergence);
        ui.columns(2, |columns| {
            self.plot(
                &mut columns[0],
                "MSE",
                |p| p.mse,
                floor.map(|c| c.mse_floor),
            );
            self.plot(
                &mut columns[1],
                "relMSE",
                |p| p.relmse,
                floor.map(|c| c.relmse_floor),
            );
        });
    }

    fn plot(
        &self,
        ui: &mut Ui,
        what: &'static str,
        value: fn(&ConvergencePoint) -> f64,
        floor: Option<f64>,
    ) {
        let runs = self.frame.as_ref().map_or(&[][..], |f| &f.runs[..]);
        Plot::new(format!("compare {what}"))
            .legend(
                Legend::default()
                    .position(Corner::LeftBottom)
                    .follow_insertion_order(true),
            )
            .x_axis_label("seconds per strategy")
            .y_axis_label(what)
            .x_axis_formatter(log_tick)
            .y_axis_formatter(log_tick)
            .link_axis(egui::Id::unique("compare plots"), [true, false])
            .allow_scroll(false)
            .label_formatter(move |pos: &HoverPosition<'_>| match pos {
                HoverPosition::NearDataPoint {
                    plot_name,
                    position,
                    ..
                } => Some(format!(
                    "{plot_name}\n{} s\n{what} {}",
                    tick_label(10f64.powf(position.x)),
                    sci(10f64.powf(position.y))
                )),
                HoverPosition::Elsewhere { .. } => None,
            })
            .show(ui, |plot_ui| {
                for run in runs {
                    let points: Vec<[f64; 2]> = run
                        .history
                        .iter()
                        .filter(|p| p.seconds > 0.0 && value(p) > 0.0)
                        .map(|p| [p.seconds.log10(), value(p).log10()])
                        .collect();
                    // Antishadow often equals another strategy exactly (projection in the
                    // antipenumbra, portal or light elsewhere): dashed, so that both show.
                    let style = if run.strategy == Strategy::Antishadow {
                        LineStyle::dashed_dense()
                    } else {
                        LineStyle::Solid
                    };
                    plot_ui.line(
                        Line::new(run.strategy.name(), points)
                            .color(strategy_colour(run.strategy))
                            .width(2.0)
                            .style(style),
                    );
                }
                if let Some(f) = floor.filter(|f| *f > 0.0) {
                    plot_ui.hline(
                        HLine::new("reference noise floor", f.log10())
                            .color(Color32::GRAY)
                            .style(LineStyle::dashed_loose()),
                    );
                }
            });
    }
}

fn log_tick(mark: GridMark, _range: &std::ops::RangeInclusive<f64>) -> String {
    tick_label(10f64.powf(mark.value))
}
