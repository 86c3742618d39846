function answer = spm_get(base_url, resource)
%SPM_GET  GET a resource of an spm-pin server (`spm serve`), decoded from JSON.
%   answer = spm_get('http://127.0.0.1:8750', '/state')
%
%   The same call in MATLAB and in GNU Octave: webread. Octave's webread answers
%   the JSON text, MATLAB's the decoded struct; both end as a struct here.
%   With a token, set the environment variable SPM_TOKEN (as for the server).
  options = weboptions('Timeout', 30);
  token = getenv('SPM_TOKEN');
  if ~isempty(token)
    options.HeaderFields = {'Authorization', ['Bearer ' token]};
  end
  answer = webread([base_url resource], options);
  if ischar(answer)
    answer = jsondecode(answer);
  end
end
