// Sortable tables and filters for the pilotlab report. No network, no innerHTML: data stays text.
(function () {
  "use strict";

  // The cell under column `column`, or null where a "not applicable: reason" cell spans it.
  function cellAt(row, column) {
    var start = 0;
    for (var i = 0; i < row.cells.length; i += 1) {
      var span = row.cells[i].colSpan || 1;
      if (column < start + span) { return span > 1 ? null : row.cells[i]; }
      start += span;
    }
    return null;
  }

  // Numbers sort by data-sort, text by its content; missing values (null) always sort last.
  function sortKey(cell) {
    if (!cell || cell.classList.contains("missing")) { return null; }
    if (cell.dataset.sort !== undefined) { return Number(cell.dataset.sort); }
    return cell.textContent.trim().toLowerCase();
  }

  function compareKeys(a, b, ascending) {
    if (a === null || b === null) { return a === b ? 0 : (a === null ? 1 : -1); }
    var order = (typeof a === "number" && typeof b === "number") ? a - b : String(a).localeCompare(String(b));
    return ascending ? order : -order;
  }

  function sortTable(table, column, header) {
    var ascending = header.getAttribute("aria-sort") !== "ascending";
    Array.prototype.forEach.call(header.parentNode.cells, function (th) { th.setAttribute("aria-sort", "none"); });
    header.setAttribute("aria-sort", ascending ? "ascending" : "descending");
    var body = table.tBodies[0];
    var keyed = Array.prototype.map.call(body.rows, function (row, index) {
      return { row: row, index: index, key: sortKey(cellAt(row, column)) };
    });
    keyed.sort(function (a, b) { return compareKeys(a.key, b.key, ascending) || a.index - b.index; });
    keyed.forEach(function (entry) { body.appendChild(entry.row); });
  }

  function makeSortable(table) {
    Array.prototype.forEach.call(table.tHead.rows[0].cells, function (header, column) {
      header.tabIndex = 0;
      header.setAttribute("aria-sort", "none");
      header.addEventListener("click", function () { sortTable(table, column, header); });
      header.addEventListener("keydown", function (event) {
        if (event.key === "Enter" || event.key === " ") { event.preventDefault(); sortTable(table, column, header); }
      });
    });
  }

  var selects = Array.prototype.slice.call(document.querySelectorAll("select[data-filter]"));
  var counter = document.getElementById("filter-count");

  // An element without the attribute (an offline row has no circuit) is not filtered on that axis.
  function matches(element, wanted) {
    return Object.keys(wanted).every(function (axis) {
      var value = element.dataset[axis];
      return value === undefined || value === wanted[axis];
    });
  }

  function applyFilters() {
    var wanted = {};
    selects.forEach(function (select) { if (select.value) { wanted[select.dataset.filter] = select.value; } });
    var items = document.querySelectorAll("[data-filterable]");
    var shown = 0;
    Array.prototype.forEach.call(items, function (item) {
      item.hidden = !matches(item, wanted);
      if (!item.hidden) { shown += 1; }
    });
    document.querySelectorAll(".table-block, .gallery-block").forEach(function (block) {
      var visible = block.querySelector("[data-filterable]:not([hidden])") !== null;
      var empty = block.querySelector(".empty");
      if (empty) { empty.hidden = visible; }
    });
    var active = Object.keys(wanted).length > 0;
    counter.textContent = active ? shown + " of " + items.length + " rows and pictures shown" : "";
  }

  document.querySelectorAll("table.sortable").forEach(makeSortable);
  selects.forEach(function (select) { select.addEventListener("change", applyFilters); });
  document.getElementById("reset-filters").addEventListener("click", function () {
    selects.forEach(function (select) { select.value = ""; });
    applyFilters();
  });
  applyFilters();
}());
