// The typed reader every stage's settings parser is written with (mcdn/settings.h,
// chain/stage_table.cpp): one && chain per stage, the first bad value's message kept.
#pragma once

#include <algorithm>
#include <string>
#include <vector>

#include <OpenImageIO/strutil.h>

#include "mcdn/settings.h"
#include "mcdn/skip.h"

namespace mcdn {

// Reads typed values out of one stage's settings; the first bad value or unknown key leaves
// its message in `error` and every later read fails too, so a parser is one && chain.
class SettingsReader {
public:
    SettingsReader(const Settings& settings, const std::string& stage, std::string& error)
        : m_settings(settings), m_error(error)
    {
        const auto& keys = setting_keys(stage);
        for (const auto& [key, value] : settings)
            if (std::find(keys.begin(), keys.end(), key) == keys.end())
                fail(OIIO::Strutil::fmt::format("{}={}: unknown setting of {} (settings: {})", key,
                                                value, stage, OIIO::Strutil::join(keys, ", ")));
    }

    bool ok() const { return m_ok; }

    // A window or patch width (odd, like the papers' 19×19) into the Options' radius.
    SettingsReader& width(const std::string& key, int& radius)
    {
        if (const std::string* v = find(key)) {
            int w = OIIO::Strutil::string_is_int(*v) ? OIIO::Strutil::stoi(*v) : 0;
            if (w < 1 || w % 2 == 0 || w > 101)
                fail(OIIO::Strutil::fmt::format("{}={} must be an odd width between 1 and 101", key,
                                                *v));
            else
                radius = (w - 1) / 2;
        }
        return *this;
    }

    SettingsReader& number(const std::string& key, float& value)
    {
        double d;
        if (const std::string* v = find(key)) {
            if (!parse_finite(*v, d))
                fail(OIIO::Strutil::fmt::format("{}={} is not a number", key, *v));
            else if (d != 0 && float(d) == 0)  // 1e-63 would reach the op as 0
                fail(OIIO::Strutil::fmt::format("{}={} is too small for a float", key, *v));
            else
                value = float(d);
        }
        return *this;
    }

    SettingsReader& positive_int(const std::string& key, int& value)
    {
        if (const std::string* v = find(key)) {
            if (!OIIO::Strutil::string_is_int(*v) || OIIO::Strutil::stoi(*v) < 1)
                fail(OIIO::Strutil::fmt::format("{}={} is not a positive whole number", key, *v));
            else
                value = OIIO::Strutil::stoi(*v);
        }
        return *this;
    }

    // 0 or 1 (mcdntool's bare ":alpha" arrives as 1).
    SettingsReader& flag(const std::string& key, bool& value)
    {
        if (const std::string* v = find(key)) {
            if (*v != "0" && *v != "1")
                fail(OIIO::Strutil::fmt::format("{}={} must be 0 or 1", key, *v));
            else
                value = *v == "1";
        }
        return *this;
    }

    SettingsReader& text(const std::string& key, std::string& value)
    {
        if (const std::string* v = find(key))
            value = *v;
        return *this;
    }

    SettingsReader& list(const std::string& key, std::vector<std::string>& value)
    {
        if (const std::string* v = find(key))
            value = OIIO::Strutil::splits(*v, ",");
        return *this;
    }

    // :skip=0 turns the stage's skipping off, :converged=X is its threshold (mcdn/skip.h).
    SettingsReader& skip(SkipOptions& o)
    {
        flag("skip", o.enabled);
        number("converged", o.max_relative_error);
        if (m_ok && !(o.max_relative_error >= 0))
            fail(OIIO::Strutil::fmt::format("converged={} must be >= 0 (a relative standard error)",
                                            m_settings.at("converged")));
        return *this;
    }

    // outliers=drop|off (0: off) of a network stage, into its Outliers enum (Drop, Off).
    template <class Outliers> SettingsReader& drop_or_off(const std::string& key, Outliers& value)
    {
        return custom(key, "must be drop or off", [&](const std::string& v) {
            if (v != "drop" && v != "off" && v != "0")
                return false;
            value = v == "drop" ? Outliers::Drop : Outliers::Off;
            return true;
        });
    }

    // A value the typed readers do not cover: `parse` sets the option and says whether the
    // text was valid; `requirement` completes the message when it was not.
    template <class Parse>
    SettingsReader& custom(const std::string& key, const char* requirement, Parse parse)
    {
        if (const std::string* v = find(key); v && !parse(*v))
            fail(OIIO::Strutil::fmt::format("{}={} {}", key, *v, requirement));
        return *this;
    }

private:
    const std::string* find(const std::string& key) const
    {
        auto it = m_settings.find(key);
        return m_ok && it != m_settings.end() ? &it->second : nullptr;
    }

    void fail(const std::string& message)
    {
        if (m_ok)
            m_error = message;
        m_ok = false;
    }

    const Settings& m_settings;
    std::string& m_error;
    bool m_ok = true;
};

}  // namespace mcdn
