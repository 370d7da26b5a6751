//! The flags of `ebiv process`, made from the library's table of settings
//! ([`ebiv::settings::settings`]): one flag per setting, with its help text, value name and
//! heading. Values are handed to the library as typed, which checks them.

use clap::{Arg, ArgAction, ArgMatches, Args, Command, FromArgMatches};
use ebiv::settings::{settings, Kind, ProcessSettings, Setting};

/// The setting flags given on the command line, in the table's order.
#[derive(Debug, Clone, Default)]
pub struct SettingFlags {
    /// `(flag, values)`; a switch has no values.
    pub given: Vec<(&'static str, Vec<String>)>,
}

impl SettingFlags {
    /// Apply the flags over `settings` (the defaults or a configuration file's).
    pub fn apply(&self, settings: &mut ProcessSettings) -> Result<(), ebiv::Error> {
        for (flag, values) in &self.given {
            settings.set_flag(flag, values)?;
        }
        Ok(())
    }
}

/// The argument of one setting.
fn argument(s: &'static Setting) -> Arg {
    let id = flag_id(s);
    let default = match (s.kind, s.default_text()) {
        (Kind::Switch, _) if s.on_by_default() => " [on by default; this flag turns it off]".into(),
        (Kind::Switch, _) | (_, None) => String::new(),
        (_, Some(text)) => format!(" [default: {text}]"),
    };
    let mut arg = Arg::new(id)
        .help(format!("{}{default}", s.summary()))
        .long_help(format!("{}{default}", s.help))
        .help_heading(s.group);
    arg = if s.positional {
        arg.index(1).value_name(s.value_name)
    } else {
        arg.long(id).visible_aliases(s.aliases.iter().copied())
    };
    if let Some(c) = s.short {
        arg = arg.short(c);
    }
    match s.kind {
        Kind::Switch => arg.action(ArgAction::SetTrue),
        Kind::Value => arg
            .value_name(s.value_name)
            .allow_hyphen_values(true)
            .action(ArgAction::Set),
        Kind::Values => arg
            .value_name(s.value_name)
            .num_args(1..)
            .action(ArgAction::Set),
    }
}

/// The flag's name (`no-deform` for a switch that is on by default), made once per setting.
fn flag_id(s: &'static Setting) -> &'static str {
    static IDS: std::sync::OnceLock<Vec<&'static str>> = std::sync::OnceLock::new();
    let ids = IDS.get_or_init(|| {
        settings()
            .iter()
            .map(|s| &*Box::leak(s.flag().into_boxed_str()))
            .collect()
    });
    let index = settings()
        .iter()
        .position(|t| std::ptr::eq(t, s))
        .expect("a setting of the table");
    ids[index]
}

impl FromArgMatches for SettingFlags {
    fn from_arg_matches(m: &ArgMatches) -> Result<Self, clap::Error> {
        let mut given = Vec::new();
        for s in settings() {
            let id = flag_id(s);
            match s.kind {
                Kind::Switch => {
                    if m.get_flag(id) {
                        given.push((id, Vec::new()));
                    }
                }
                Kind::Value | Kind::Values => {
                    if let Some(values) = m.get_many::<String>(id) {
                        given.push((id, values.cloned().collect()));
                    }
                }
            }
        }
        Ok(SettingFlags { given })
    }

    fn update_from_arg_matches(&mut self, m: &ArgMatches) -> Result<(), clap::Error> {
        *self = Self::from_arg_matches(m)?;
        Ok(())
    }
}

impl Args for SettingFlags {
    fn augment_args(cmd: Command) -> Command {
        settings().iter().fold(cmd, |cmd, s| cmd.arg(argument(s)))
    }

    fn augment_args_for_update(cmd: Command) -> Command {
        Self::augment_args(cmd)
    }
}

/// The denoising flags alone (`--denoise`, `--denoise-dt`, …), for the commands that read a
/// recording without measuring it: the same settings, help texts and defaults as
/// `ebiv process`'s ([`ebiv::settings::DENOISE_GROUP`]).
#[derive(Debug, Clone, Default)]
pub struct DenoiseFlags(SettingFlags);

fn is_denoise(s: &Setting) -> bool {
    s.group == ebiv::settings::DENOISE_GROUP
}

impl DenoiseFlags {
    /// The filters the flags ask for, checked; `None` when none runs.
    pub fn settings(&self) -> Result<Option<ebiv::denoise::DenoiseSettings>, ebiv::Error> {
        let mut settings = ProcessSettings::default();
        self.0.apply(&mut settings)?;
        let denoise = settings.denoise_settings();
        if let Some(d) = &denoise {
            d.check()?;
        }
        Ok(denoise)
    }
}

impl FromArgMatches for DenoiseFlags {
    fn from_arg_matches(m: &ArgMatches) -> Result<Self, clap::Error> {
        let mut given = Vec::new();
        for s in settings().iter().filter(|s| is_denoise(s)) {
            let id = flag_id(s);
            if let Some(values) = m.get_many::<String>(id) {
                given.push((id, values.cloned().collect()));
            }
        }
        Ok(DenoiseFlags(SettingFlags { given }))
    }

    fn update_from_arg_matches(&mut self, m: &ArgMatches) -> Result<(), clap::Error> {
        *self = Self::from_arg_matches(m)?;
        Ok(())
    }
}

impl Args for DenoiseFlags {
    fn augment_args(cmd: Command) -> Command {
        settings()
            .iter()
            .filter(|s| is_denoise(s))
            .fold(cmd, |cmd, s| cmd.arg(argument(s)))
    }

    fn augment_args_for_update(cmd: Command) -> Command {
        Self::augment_args(cmd)
    }
}
