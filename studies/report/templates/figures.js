// The report's interactive figures (studies/report/interactive.py writes their data): each div of
// class "interactive" is drawn from the JSON script element its data-figure attribute names,
// with BokehJS's plotting API: panels of lines and points, hover shows the case, a legend click hides a
// series, the wheel zooms.
(function () {
  "use strict";
  function panel(spec) {
    const plt = Bokeh.Plotting;
    const figure = plt.figure({
      width: 460, height: 330, title: spec.title, x_axis_type: spec.x_log ? "log" : "linear",
      y_axis_type: "log", tools: "pan,wheel_zoom,box_zoom,reset,save",
      x_axis_label: spec.x_label, y_axis_label: spec.y_label,
    });
    const points = [];
    for (const series of spec.series) {
      const source = new Bokeh.ColumnDataSource({data: series.data});
      figure.line({field: "x"}, {field: "y"}, {source: source, line_color: series.colour, line_width: 1.5,
                                               legend_label: series.name});
      points.push(figure.scatter({field: "x"}, {field: "y"}, {source: source, fill_color: series.colour,
                                                              line_color: series.colour, size: 6,
                                                              legend_label: series.name}));
    }
    for (const guide of spec.guides) {
      figure.line(guide.x, guide.y, {line_color: "#888888", line_dash: "dotted", legend_label: guide.name});
    }
    if (spec.failed) {     // failed cases: red crosses on the bottom, never a number
      const source = new Bokeh.ColumnDataSource({data: spec.failed});
      points.push(figure.scatter({field: "x"}, {field: "y"}, {source: source, marker: "x", line_color: "red",
                                                              size: 10, line_width: 2, legend_label: "failed case"}));
    }
    figure.add_tools(new Bokeh.HoverTool({renderers: points, tooltips: spec.tooltips}));
    for (const legend of figure.select(Bokeh.Legend)) {
      legend.click_policy = "hide";
      legend.label_text_font_size = "8pt";
      legend.background_fill_alpha = 0.7;
    }
    return figure;
  }
  function draw() {
    for (const element of document.querySelectorAll("div.interactive[data-figure]")) {
      const spec = JSON.parse(document.getElementById(element.dataset.figure).textContent);
      const panels = spec.panels.map(panel);
      const rows = [];
      for (let i = 0; i < panels.length; i += 2) rows.push([panels[i], i + 1 < panels.length ? panels[i + 1] : null]);
      Bokeh.Plotting.show(panels.length > 1 ? Bokeh.Plotting.gridplot(rows) : panels[0], element);
    }
  }
  if (document.readyState === "loading") document.addEventListener("DOMContentLoaded", draw);
  else draw();
})();
