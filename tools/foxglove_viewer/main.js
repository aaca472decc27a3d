// Mounts the studio-base App with an in-memory app configuration and a layout storage that holds
// one layout (id "deckpose", fetched from the page's ?layout= URL), then opens the ?ds= deep link.
/* global React, ReactDOM */
"use strict";

(function () {
  const studio = window; // the UMD bundle put its exports on the global object
  const params = new URL(window.location.href).searchParams;
  window.__deckpose = { errors: [], mounted: false };
  window.addEventListener("error", (ev) => window.__deckpose.errors.push(String(ev.message)));
  window.addEventListener("unhandledrejection", (ev) =>
    window.__deckpose.errors.push(`unhandled rejection: ${String(ev.reason && (ev.reason.stack || ev.reason))}`));

  // In-memory app settings: no welcome dialog, no sign-in prompt, no telemetry, a dark theme.
  const settings = new Map([
    ["ui.open-dialog-startup", false],
    ["hideSignInPrompt", true],
    ["telemetry.telemetryEnabled", false],
    ["telemetry.crashReportingEnabled", false],
    ["updates.enabled", false],
    ["colorScheme", "dark"],
    ["timezone", "UTC"],
  ]);
  const listeners = new Map();
  const appConfiguration = {
    get: (key) => settings.get(key),
    set: async (key, value) => {
      settings.set(key, value);
      for (const cb of listeners.get(key) ?? []) cb(value);
    },
    addChangeListener: (key, cb) => listeners.set(key, [...(listeners.get(key) ?? []), cb]),
    removeChangeListener: (key, cb) => listeners.set(key, (listeners.get(key) ?? []).filter((c) => c !== cb)),
  };

  function layoutStorage(layouts) {
    // ILayoutStorage, one map for every namespace.
    const byId = new Map(layouts.map((l) => [l.id, l]));
    return {
      list: async () => [...byId.values()],
      get: async (_ns, id) => byId.get(id),
      put: async (_ns, layout) => { byId.set(layout.id, layout); return layout; },
      delete: async (_ns, id) => { byId.delete(id); },
      importLayouts: async () => {},
      migrateUnnamespacedLayouts: async () => {},
    };
  }

  async function main() {
    const layoutUrl = params.get("layout");
    const layouts = [];
    if (layoutUrl) {
      const response = await fetch(layoutUrl);
      if (!response.ok) throw new Error(`layout ${layoutUrl}: HTTP ${response.status}`);
      const data = await response.json();
      // Stored as the app stores an imported layout; migrateLayout applies the app's own migrations.
      layouts.push(studio.migrateLayout({ id: "deckpose", name: "deckpose", permission: "CREATOR_WRITE",
        baseline: { data, savedAt: new Date().toISOString() }, working: undefined, syncInfo: undefined }));
    }
    studio.overwriteFetch();
    await studio.waitForFonts();
    await studio.initI18n();
    const dataSources = [new studio.RemoteDataSourceFactory(), new studio.McapLocalDataSourceFactory()];
    const app = React.createElement(studio.App, {
      deepLinks: [window.location.href],
      appConfiguration,
      dataSources,
      layoutStorage: layoutStorage(layouts),
      extensionLoaders: [],
      enableGlobalCss: true,
      enableLaunchPreferenceScreen: false,
    });
    ReactDOM.render(app, document.getElementById("root"));
    window.__deckpose.mounted = true;
  }

  main().catch((err) => window.__deckpose.errors.push(`mount: ${String(err && (err.stack || err))}`));
})();
